"""The exact search's starting incumbent: construction and ascent against a plain-numpy twin,
and the search's answer unchanged by it (the first optimum in the search's order)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.assignment_exact import AssignmentSearch, agent_order, solve_assignment_exact
from trackjam.control.assignment_incumbent import kernel_incumbent
from trackjam.control.assignment_problem import assignment_value, target_xi
from trackjam.control.exact import solve_exact
from trackjam.control.objective import received_interference

from control_instances import small_displacements
from test_assignment import enumerate_assignment, random_assignment, slots


def choice_values(P, pair, target, i, placed):
    """Team objective (-inf where Eq. 13 is enforced and broken) of every choice of agent i,
    the others fixed, in the kernel's order (target, then candidate, then level); agents not
    ``placed`` serve nobody but count in Eq. (13)."""
    N, K, L, C = P.n_agents, P.n_targets, P.n_levels, P.n_slots
    k, c, lv = (a.ravel() for a in np.meshgrid(np.arange(K), np.arange(P.n_cand[i]), np.arange(L), indexing="ij"))
    T = np.tile(target, (len(k), 1))
    cand = np.tile(pair // L, (len(k), 1))
    level = np.tile(pair % L, (len(k), 1))
    T[:, i], cand[:, i], level[:, i] = k, c, lv
    xi = target_xi(P, cand, level, np.where(placed, T, K))
    value = xi.sum(axis=-1) if P.objective == "sum" else xi.min(axis=-1)
    ok = np.all(received_interference(P.gain, P.levels_w, T * C + cand, level) < P.delta_w, axis=-1)
    return (np.where(ok, value, -np.inf) if P.constraints else value), k, c * L + lv


def incumbent_twin(P):
    """Plain-numpy twin of ``kernel_incumbent`` from the all-hover start."""
    N = P.n_agents
    pair, target = np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.int64)
    placed = np.zeros(N, dtype=bool)
    for i in agent_order(P):
        placed[i] = True
        value, k, pr = choice_values(P, pair, target, i, placed)
        s = int(np.argmax(value))
        pair[i], target[i] = pr[s], k[s]
    value, ok = assignment_value(P, pair // P.n_levels, pair % P.n_levels, target)
    best = float(value) if (ok or not P.constraints) else -np.inf
    changed = True
    while changed:
        changed = False
        for i in range(N):
            value, k, pr = choice_values(P, pair, target, i, placed)
            s = int(np.argmax(value))
            if value[s] > best:
                best, pair[i], target[i], changed = float(value[s]), pr[s], k[s], True
    return best, pair, target


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 4), st.integers(1, 3), st.sampled_from(["sum", "min"]),
       st.booleans())
def test_incumbent_kernel_equals_numpy_twin(antenna, seed, n_agents, n_targets, objective, constraints):
    rng = np.random.default_rng(seed)
    P = random_assignment(rng, antenna, n_agents, n_targets, 1 + seed % n_agents, constraints, objective,
                          small_displacements(), spread=rng.uniform(3, 12))
    pair, target = np.zeros(n_agents, dtype=np.int64), np.zeros(n_agents, dtype=np.int64)
    value = kernel_incumbent(P.pz, P.gain, P.levels_w, P.delta_w, P.at_least, P.kind, P.constraints, P.n_cand,
                             agent_order(P), pair, target)
    twin_value, twin_pair, twin_target = incumbent_twin(P)
    assert value == twin_value
    np.testing.assert_array_equal(pair, twin_pair)
    np.testing.assert_array_equal(target, twin_target)
    # the start is feasible (every agent silent), so the incumbent is too, and it is no worse
    v, ok = assignment_value(P, pair // P.n_levels, pair % P.n_levels, target)
    assert (ok or not constraints) and v == value
    z = np.zeros(n_agents, dtype=np.int64)
    assert value >= assignment_value(P, z, z, z)[0]


@pytest.mark.parametrize("objective", ["sum", "min"])
def test_search_answer_is_the_first_optimum_whatever_the_incumbent(antenna, objective):
    """The incumbent only prunes: the search still returns the enumeration's first optimum in its
    order, and visits no more nodes than from the silent start."""
    rng = np.random.default_rng(7)
    for trial in range(8):
        P = random_assignment(rng, antenna, 3, 2, 1 + trial % 3, True, objective, spread=5.0 + trial)
        value, cand, level, target = enumerate_assignment(P)
        sol = solve_assignment_exact(P)
        assert sol.objective == value and sol.optimal
        assert np.array_equal(slots(P, sol), cand) and np.array_equal(sol.level, level)
        assert np.array_equal(sol.target, target)
        silent = AssignmentSearch(P, incumbent=False)
        silent.run()
        assert sol.nodes <= silent.nodes


@pytest.mark.parametrize("n_agents,n_targets", [(1, 1), (1, 3), (3, 1), (3, 2), (2, 3), (3, 3)])
def test_coverage_bound_keeps_the_first_optimum(antenna, n_agents, n_targets):
    """n = 1 with `sum` adds the coverage bound (each agent counted once): the search still
    returns the enumeration's first optimum, and with one target today's one-target plan."""
    rng = np.random.default_rng(40 + 10 * n_agents + n_targets)
    for trial in range(5):
        P = random_assignment(rng, antenna, n_agents, n_targets, 1, trial % 2 == 0, "sum", spread=4.0 + 2 * trial)
        value, cand, level, target = enumerate_assignment(P)
        sol = solve_assignment_exact(P)
        assert sol.objective == value and sol.optimal
        assert np.array_equal(slots(P, sol), cand) and np.array_equal(sol.level, level)
        assert np.array_equal(sol.target, target)
        if n_targets == 1:
            today = solve_exact(P.targets[0])
            assert np.array_equal(sol.move, today.move) and np.array_equal(sol.level, today.level)
