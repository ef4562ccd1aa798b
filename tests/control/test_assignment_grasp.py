"""GRASP over (move, level, target): the compiled search follows its numpy twin draw for draw,
never returns a plan that breaks Eq. (13), and reaches the exact optimum on small problems."""

import numpy as np
import pytest

from trackjam.control.assignment_exact import solve_assignment_exact
from trackjam.control.assignment_grasp import (
    assignment_grasp_chunked,
    assignment_grasp_reference,
    solve_assignment_grasp,
)
from trackjam.control.assignment_problem import assignment_value
from trackjam.control.grasp import neighbour_lists

from test_assignment import random_assignment, slots
from control_instances import small_displacements


@pytest.mark.parametrize("objective", ["sum", "min"])
@pytest.mark.parametrize("n_targets", [1, 2, 3])
def test_kernel_follows_numpy_reference(antenna, objective, n_targets):
    rng = np.random.default_rng(n_targets)
    P = random_assignment(rng, antenna, 3, n_targets, 2, True, objective, small_displacements(), spread=6.0)
    assert_search_follows_its_twin(P, range(P.n_agents), 50, 5)


def assert_search_follows_its_twin(P, agents, samples: int, iterations: int) -> None:
    """Each of ``agents``' compiled searches equals the numpy twin's: value, plan and the random
    stream both consumed."""
    neigh, n_neigh = neighbour_lists(P.targets[0], 4)
    for me in agents:
        pair = np.zeros(P.n_agents, dtype=np.int64)
        target = np.zeros(P.n_agents, dtype=np.int64)
        r1, r2 = np.random.default_rng(me), np.random.default_rng(me)
        v = assignment_grasp_chunked(r1, me, P.pz, P.gain, P.levels_w, P.delta_w, P.at_least, P.kind,
                                    P.constraints, P.n_cand, neigh, n_neigh, samples, iterations, pair, target)
        v_ref, p_ref, t_ref = assignment_grasp_reference(r2, me, P, neigh, n_neigh, samples, iterations)
        assert v == v_ref and np.array_equal(pair, p_ref) and np.array_equal(target, t_ref)
        assert r1.random() == r2.random()  # both drew the same stream


@pytest.mark.parametrize("objective", ["sum", "min"])
def test_grasp_is_feasible_and_never_beats_exact(antenna, objective):
    rng = np.random.default_rng(7)
    for trial in range(8):
        P = random_assignment(rng, antenna, 3, 2, 1 + trial % 3, True, objective, small_displacements(),
                              spread=3.0 + trial)
        sol = solve_assignment_grasp(P, [np.random.default_rng([trial, j]) for j in range(3)], 200, 5, 4)
        value, ok = assignment_value(P, slots(P, sol), sol.level, sol.target)
        assert sol.feasible and bool(ok) and sol.objective == float(value)
        assert sol.objective <= solve_assignment_exact(P).objective


@pytest.mark.parametrize("objective", ["sum", "min"])
def test_grasp_reaches_the_optimum_on_small_problems(antenna, objective):
    rng = np.random.default_rng(8)
    for trial in range(4):
        P = random_assignment(rng, antenna, 2, 2, 1 + trial % 2, True, objective, spread=6.0)
        sol = solve_assignment_grasp(P, [np.random.default_rng([trial, j]) for j in range(2)], 3000, 30, 6)
        assert sol.objective == solve_assignment_exact(P).objective


def test_same_streams_same_plan_and_threads_change_nothing(antenna):
    P = random_assignment(np.random.default_rng(9), antenna, 3, 2, 2, True, "sum", small_displacements())

    def run(threads):
        return solve_assignment_grasp(P, [np.random.default_rng([1, j]) for j in range(3)], 300, 5, 4, threads)

    a, b, c = run(1), run(1), run(2)
    for s in (b, c):
        assert np.array_equal(a.move, s.move) and np.array_equal(a.level, s.level)
        assert np.array_equal(a.target, s.target) and a.objective == s.objective


@pytest.mark.parametrize("at_least", [1, 3, 4])
def test_both_sampling_loops_follow_the_numpy_reference(antenna, at_least):
    """The compiled search's loop for n <= 3 and its general loop (n = 4 here) each follow the
    numpy twin draw for draw, with five agents and two targets."""
    rng = np.random.default_rng(at_least)
    P = random_assignment(rng, antenna, 5, 2, at_least, True, "sum", small_displacements(), spread=6.0)
    assert_search_follows_its_twin(P, (0, 4), 60, 4)


@pytest.mark.parametrize("objective", ["sum", "min"])
def test_one_agent_follows_its_twin_and_reaches_the_enumerated_optimum(antenna, objective):
    """N = 1 (the tests above take two agents or more): the compiled search equals its numpy
    twin draw for draw, and finds the optimum of the full enumeration over (move, level, target)."""
    from test_assignment import enumerate_assignment

    rng = np.random.default_rng(17)
    for trial in range(3):
        P = random_assignment(rng, antenna, 1, 1 + trial, 1, True, objective, spread=4.0)
        assert_search_follows_its_twin(P, [0], 50, 4)
        value = enumerate_assignment(P)[0]
        sol = solve_assignment_grasp(P, [np.random.default_rng([trial, 0])], 1000, 5, 4)
        assert sol.objective == value and sol.feasible
