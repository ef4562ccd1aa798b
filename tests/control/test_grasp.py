"""The paper's GRASP: never better than the optimum, reaches it on tiny instances, always
feasible when the constraints are on, and its compiled search follows its numpy reference."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.exact import solve_exact
from trackjam.control.grasp import neighbour_lists, solve_grasp
from trackjam.control.objective import evaluate

from control_instances import assert_grasp_kernel_follows_its_twin, random_problem, tiny_displacements


def rngs(seed, n):
    return [np.random.default_rng([seed, j]) for j in range(n)]


def test_kernel_follows_numpy_reference(antenna):
    rng = np.random.default_rng(5)
    for trial in range(4):
        P = random_problem(rng, antenna, 3, 1 + trial % 3, constraints=trial % 2 == 0)
        assert_grasp_kernel_follows_its_twin(P, trial, 200, 15)


def test_neighbours_are_the_nearest_other_displacements(antenna):
    P = random_problem(np.random.default_rng(0), antenna)
    neigh, n_neigh = neighbour_lists(P, 6)
    D = P.displacements[P.move[0, : P.n_cand[0]]]
    for c in range(P.n_cand[0]):
        d = np.linalg.norm(D - D[c], axis=1)
        chosen = d[neigh[0, c, : n_neigh[0, c]]]
        assert c not in neigh[0, c, : n_neigh[0, c]]
        others = np.delete(d, np.r_[c, neigh[0, c, : n_neigh[0, c]]])
        assert chosen.max() <= others.min() + 1e-12


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 3), st.booleans())
def test_grasp_is_feasible_and_never_beats_exact(antenna, seed, at_least, constraints):
    rng = np.random.default_rng(seed)
    P = random_problem(rng, antenna, 3, at_least, constraints, spread=rng.uniform(3, 20))
    g = solve_grasp(P, rngs(seed, 3), samples=200, iterations=5)
    e = solve_exact(P)
    assert g.objective <= e.objective + 1e-12
    if constraints:
        assert g.feasible
    xi, ok = evaluate(P, [np.flatnonzero(P.move[i] == g.move[i])[0] for i in range(3)], g.level)
    assert np.isclose(xi, g.objective) and ok == g.feasible


def test_grasp_reaches_the_optimum_on_tiny_instances(antenna):
    rng = np.random.default_rng(11)
    for trial in range(6):
        P = random_problem(rng, antenna, 2 + trial % 2, 1 + trial % 2, trial % 3 != 0,
                           displacements=tiny_displacements())
        g = solve_grasp(P, rngs(trial, P.n_agents), samples=2000, iterations=20)
        assert g.objective == solve_exact(P).objective


def test_threads_do_not_change_the_result(antenna):
    P = random_problem(np.random.default_rng(3), antenna)
    a = solve_grasp(P, rngs(1, 3), samples=300, iterations=5, threads=1)
    b = solve_grasp(P, rngs(1, 3), samples=300, iterations=5, threads=3)
    assert np.array_equal(a.move, b.move) and np.array_equal(a.level, b.level)


def test_same_seed_same_solution(antenna):
    P = random_problem(np.random.default_rng(4), antenna)
    a = solve_grasp(P, rngs(9, 3), samples=300, iterations=5)
    b = solve_grasp(P, rngs(9, 3), samples=300, iterations=5)
    assert np.array_equal(a.move, b.move) and np.array_equal(a.level, b.level)
