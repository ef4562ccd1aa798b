"""The exact solver is the optimum of Eqs. (12)-(13): full enumeration agrees with it."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.exact import enumerate_optimum, solve_exact

from control_instances import random_problem, tiny_displacements


@pytest.mark.parametrize("n_agents", [2, 3])
@pytest.mark.parametrize("constraints", [True, False])
def test_exact_equals_full_enumeration(antenna, n_agents, constraints):
    rng = np.random.default_rng(10 * n_agents + constraints)
    for trial in range(12):
        at_least = 1 + trial % n_agents
        P = random_problem(rng, antenna, n_agents, at_least, constraints, spread=6.0 + trial)
        value, cand, level = enumerate_optimum(P)
        sol = solve_exact(P)
        assert sol.objective == pytest.approx(value, rel=1e-12, abs=1e-15)
        assert np.array_equal(sol.move, P.move[np.arange(n_agents), cand])
        assert np.array_equal(sol.level, level)
        if constraints:
            assert sol.feasible


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 3), st.integers(1, 3))
def test_removing_constraints_never_lowers_the_optimum(antenna, seed, n_agents, at_least):
    at_least = min(at_least, n_agents)
    rng = np.random.default_rng(seed)
    on = random_problem(rng, antenna, n_agents, at_least, True, displacements=tiny_displacements())
    off = random_problem(np.random.default_rng(seed), antenna, n_agents, at_least, False,
                         displacements=tiny_displacements())
    assert solve_exact(off).objective >= solve_exact(on).objective


def test_all_off_when_nobody_can_see_the_aim(antenna):
    from trackjam.control.problem import build_problem

    from control_instances import HIGH, LOW, small_displacements

    # agents far beyond the cone's reach of the aim: p_D = 0 everywhere
    P = build_problem([[0, 0, 0], [100, 100, 100]], [50, 0, 100], small_displacements(), antenna, LOW, HIGH, 1, True)
    sol = solve_exact(P)
    assert sol.objective == 0 and np.all(sol.move == 0) and np.all(sol.level == 0)
