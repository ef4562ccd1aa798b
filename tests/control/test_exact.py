"""The exact solver is the optimum of Eqs. (12)-(13): full enumeration agrees with it; stopped
early it returns a feasible plan whose certified gap covers the distance to the optimum."""

import threading
import _thread

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.exact import BranchAndBound, enumerate_optimum, solve_exact
from trackjam.control.objective import evaluate

from control_instances import random_problem, tiny_displacements


def slots(P, sol):
    return np.array([int(np.flatnonzero(P.move[i] == sol.move[i])[0]) for i in range(P.n_agents)])


@pytest.mark.parametrize("n_agents", [1, 2, 3])  # N = 1: one agent, no Eq. (13) partner
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
        assert sol.optimal and sol.gap == 0.0 and sol.nodes > 0
        if constraints:
            assert sol.feasible


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 3), st.integers(1, 3), st.booleans(),
       st.sampled_from([1, 2, 5, 20, 100]))
def test_a_stopped_search_certifies_its_gap(antenna, seed, n_agents, at_least, constraints, node_limit):
    rng = np.random.default_rng(seed)
    P = random_problem(rng, antenna, n_agents, min(at_least, n_agents), constraints,
                       spread=rng.uniform(3, 15))
    optimum = enumerate_optimum(P)[0]
    sol = solve_exact(P, node_limit=node_limit)
    xi, ok = evaluate(P, slots(P, sol), sol.level)
    assert sol.objective == float(xi)
    assert ok or not constraints
    assert sol.nodes <= node_limit
    assert sol.objective + sol.gap >= optimum - 1e-12
    assert sol.objective <= optimum + 1e-12
    if sol.optimal:
        assert sol.gap == 0.0 and sol.objective == pytest.approx(optimum, rel=1e-12, abs=1e-15)
    else:
        assert sol.gap > 0.0


def test_a_search_run_in_chunks_is_the_search_run_at_once(antenna):
    rng = np.random.default_rng(8)
    pauses = 0
    for trial in range(5):
        P = random_problem(rng, antenna, 4, 2, trial % 2 == 0, spread=8.0)
        whole = BranchAndBound(P)
        assert whole.step(0)
        chunked = BranchAndBound(P)
        while not chunked.step(3):
            pauses += 1
        assert chunked.nodes == whole.nodes and chunked.value == whole.value
        assert np.array_equal(chunked.best_cand, whole.best_cand)
        assert np.array_equal(chunked.best_level, whole.best_level)
    assert pauses > 0


def test_more_nodes_never_lower_the_plan_and_enough_prove_it(antenna):
    P = random_problem(np.random.default_rng(2), antenna, 3, 2, True, spread=6.0)
    optimum = enumerate_optimum(P)[0]
    sols = [solve_exact(P, node_limit=k) for k in (1, 4, 16, 64, 256, 1 << 20)]
    values = [s.objective for s in sols]
    assert all(b >= a for a, b in zip(values, values[1:]))
    assert all(s.objective + s.gap >= optimum - 1e-12 for s in sols)
    assert sols[0].gap > 0.0 and not sols[0].optimal
    assert sols[-1].optimal and sols[-1].gap == 0.0


def test_ctrl_c_stops_a_long_exact_search(antenna):
    from control_instances import HIGH, LOW
    from trackjam.control.problem import build_problem
    from trackjam.world.moves import displacement_set

    rng = np.random.default_rng(0)
    x = np.full(3, 50.0)
    u = x + rng.normal(0, 8, (8, 3))
    P = build_problem(u, x, displacement_set([1.0, 3.0, 5.0], 8, 8), antenna, LOW, HIGH, 2, True)
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            solve_exact(P, time_limit_s=600.0)
    finally:
        timer.cancel()


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


def test_placing_agents_one_by_one_accumulates_eq_13s_received_powers():
    """recv[d, j] after placing agents 0..d is the power agent j receives from the others of 0..d."""
    from trackjam.control.exact import _place
    from trackjam.control.objective import received_interference

    rng = np.random.default_rng(6)
    for _ in range(30):
        N, C = int(rng.integers(1, 6)), 4
        gain = rng.uniform(0, 1, (N, N, C, C))
        gain[np.arange(N), np.arange(N)] = 0.0  # an agent does not jam itself
        levels_w = np.array([0.0, 0.5, 1.0, 2.0])
        c, lv = rng.integers(0, C, N), rng.integers(0, 4, N)
        recv = np.full((N, N), np.nan)
        for d in range(N):
            _place(d, gain, levels_w, c, lv, recv)
            ref = received_interference(gain[: d + 1, : d + 1], levels_w, c[: d + 1], lv[: d + 1])
            assert np.allclose(recv[d, : d + 1], ref, rtol=1e-12, atol=0)


def test_xi_is_linear_in_one_agents_p_d_with_the_kernels_coefficients():
    """The bound of a pair costs S multiply-adds: Xi = A + B p_D^d, A and B from the others."""
    from trackjam.control.exact import _others_dp
    from trackjam.control.objective import at_least_probability

    rng = np.random.default_rng(4)
    for _ in range(30):
        S, N = int(rng.integers(1, 5)), int(rng.integers(1, 6))
        n = int(rng.integers(1, N + 1))
        d = int(rng.integers(0, N))
        p = rng.uniform(0, 1, (S, N))
        smax = rng.uniform(0, 1, (S, N, 7))
        bptr = rng.integers(0, 7, (N + 1, N))
        AB = np.zeros((N, S, 2))
        _others_dp(d, n, p, smax, bptr, AB)
        for s in range(S):
            others = np.array([p[s, j] if j < d else smax[s, j, bptr[d, j]] for j in range(N) if j != d])
            A = at_least_probability(others, n)
            B = at_least_probability(others, n - 1) - A
            assert AB[d, s, 0] == pytest.approx(A, abs=1e-14) and AB[d, s, 1] == pytest.approx(B, abs=1e-14)
            x = rng.uniform()
            full = at_least_probability(np.insert(others, d, x), n)
            assert AB[d, s, 0] + AB[d, s, 1] * x == pytest.approx(full, abs=1e-14)


def test_ranked_tables_kernel_is_its_numpy_twin_bit_for_bit(antenna):
    """kernel_ranked_tables (p_D by rank, zero past the real pairs, and its suffix maximum)
    equals ranked_tables_reference, on point and belief problems with padded candidates."""
    from trackjam.control.exact import kernel_ranked_tables, pair_order, ranked_tables_reference
    from trackjam.control.problem import build_problem

    from control_instances import HIGH, LOW, small_displacements

    rng = np.random.default_rng(21)
    for trial in range(6):
        x = rng.uniform(5, 95, 3)
        u = np.clip(x + rng.normal(0, 8, (3, 3)), 0, 100)
        u[0, 2] = 0.0  # on the floor: fewer candidates, padded pairs
        xs = x + rng.normal(0, 6, (1 + 8 * (trial % 2), 3))
        P = build_problem(u, x, small_displacements(), antenna, LOW, HIGH, 2, True, xs if trial > 1 else None)
        L = P.n_levels
        order, n_pairs = pair_order(P)
        valid = order >= 0
        rank_c, rank_l = np.where(valid, order // L, 0), np.where(valid, order % L, 0)
        p_s = np.ascontiguousarray(P.objective_tables()[0])
        ps, smax = kernel_ranked_tables(p_s, rank_c, rank_l, n_pairs)
        ps_ref, smax_ref = ranked_tables_reference(p_s, rank_c, rank_l, n_pairs)
        assert np.count_nonzero(~valid) > 0
        assert np.array_equal(ps, ps_ref) and np.array_equal(smax, smax_ref)


def test_pair_order_is_each_agents_own_sort(antenna):
    """pair_order's one sort gives every agent the ranks a sort of its own pairs gives (p_D
    descending, then level, then move), ties included (off levels all have p_D 0)."""
    from trackjam.control.exact import pair_order

    rng = np.random.default_rng(22)
    for _ in range(5):
        P = random_problem(rng, antenna, 3, 2, True, spread=20.0)
        order, n_pairs = pair_order(P)
        L = P.n_levels
        for i in range(P.n_agents):
            n = int(P.n_cand[i])
            c, l = np.divmod(np.arange(n * L), L)
            rank = np.lexsort((c, l, -P.p_d[i, c, l]))
            assert np.array_equal(order[i, : n * L], c[rank] * L + l[rank])
            assert np.all(order[i, n * L:] == -1) and n_pairs[i] == n * L
