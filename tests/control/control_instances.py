"""Random paper-like instances shared by the control tests."""

import numpy as np

from trackjam.control.grasp import grasp_search_chunked, grasp_search_reference, neighbour_lists
from trackjam.control.problem import build_problem
from trackjam.world.moves import displacement_set

LOW, HIGH = (0.0, 0.0, 0.0), (100.0, 100.0, 100.0)


def small_displacements() -> np.ndarray:
    """Table I's 11 controls (one 3 m step, N_phi = 4, N_theta = 8)."""
    return displacement_set([3.0], 4, 8)


def tiny_displacements() -> np.ndarray:
    """Hover and 6 axis moves of 4 m."""
    return displacement_set([4.0], 4, 4)


def random_problem(rng, antenna, n_agents=3, at_least=2, constraints=True, displacements=None, spread=8.0):
    """A paper-like instance: agents scattered around the aim, which the antennas point at."""
    D = small_displacements() if displacements is None else displacements
    x = rng.uniform(5, 95, 3)
    u = np.clip(x + rng.normal(0, spread, (n_agents, 3)), 0, 100)
    return build_problem(u, x, D, antenna, LOW, HIGH, at_least, constraints)


def assert_grasp_kernel_follows_its_twin(P, seed: int, samples: int, iterations: int, neighbours: int = 4) -> None:
    """Every agent's compiled GRASP search (one chunk) equals its numpy twin on ``P``: value, plan and the
    random stream both consumed."""
    neigh, n_neigh = neighbour_lists(P, neighbours)
    for me in range(P.n_agents):
        c = np.zeros(P.n_agents, dtype=np.int64)
        l = np.zeros(P.n_agents, dtype=np.int64)
        r1, r2 = np.random.default_rng(seed), np.random.default_rng(seed)
        v = grasp_search_chunked(r1, me, P.objective_tables(), P.gain, P.levels_w, P.delta_w, P.at_least,
                                P.constraints, P.n_cand, neigh, n_neigh, samples, iterations, c, l)
        v_ref, c_ref, l_ref = grasp_search_reference(r2, me, P, neigh, n_neigh, samples, iterations, c * 0, l * 0)
        assert v == v_ref and np.array_equal(c, c_ref) and np.array_equal(l, l_ref)
        assert r1.random() == r2.random()  # both drew the same stream
