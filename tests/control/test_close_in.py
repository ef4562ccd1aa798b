"""``control.close_in`` (ours): a team whose best plan under Eq. (13) is worth less than the
threshold moves as the plan without Eq. (13) would and chooses its levels under Eq. (13) there.
Held to brute force over every level vector on small instances."""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from trackjam.control.distributed import own_searches
from trackjam.control.objective import evaluate
from trackjam.control.problem import build_problem
from trackjam.control.solve import solve

from control_instances import HIGH, LOW, random_problem, tiny_displacements

THRESHOLD = 0.05


def _search(P, solver="exact", close_in=None, seed=0, rows=(0,)):
    rngs = [np.random.default_rng(seed + k) for k in range(len(rows))]
    return own_searches(P, solver, list(rows), rngs, 2000, 20, 4, 1, None, 0, close_in)


def _best_levels(P, cand):
    """Brute force: the highest Xi under Eq. (13) over every level vector at slots ``cand``."""
    best = -1.0
    for lv in itertools.product(range(P.n_levels), repeat=P.n_agents):
        xi, ok = evaluate(P, cand, np.array(lv))
        if ok and xi > best:
            best = float(xi)
    return best


def _traps(antenna, n, displacements=None, spread=30.0):
    """Instances whose constrained optimum is worth less than THRESHOLD while the plan without
    Eq. (13) is worth more and moves the agents elsewhere: where closing in changes the plan."""
    rng = np.random.default_rng(7)
    found = []
    for _ in range(400):
        P = random_problem(rng, antenna, spread=spread, displacements=displacements)
        low = solve(P, "exact", [], time_limit_s=None)
        free = solve(replace(P, constraints=False), "exact", [], time_limit_s=None)
        if low.objective < THRESHOLD < free.objective and not np.array_equal(low.move, free.move):
            found.append(P)
            if len(found) == n:
                break
    assert len(found) == n, "no trap instance found: the test would assert nothing"
    return found


def test_fixed_at_matches_the_full_problem(antenna):
    """Every level vector of the problem held at slots ``cand`` has the full problem's Xi and
    Eq. (13) at those slots, with and without belief samples."""
    rng = np.random.default_rng(3)
    for samples in (None, rng.normal(0.0, 3.0, (5, 3))):
        P = random_problem(rng, antenna, spread=12.0)
        if samples is not None:
            P = build_problem(P.positions, P.aim, P.displacements, antenna, LOW, HIGH, 2, True, P.aim + samples)
            assert P.p_d_samples is not None
        cand = np.array([rng.integers(P.n_cand[i]) for i in range(P.n_agents)])
        F = P.fixed_at(cand)
        assert np.array_equal(F.n_cand, np.ones(P.n_agents))
        assert np.array_equal(F.move[:, 0], P.move[np.arange(P.n_agents), cand])
        assert np.array_equal(P.slots_of(F.move[:, 0]), cand)
        for lv in itertools.product(range(P.n_levels), repeat=P.n_agents):
            lv = np.array(lv)
            xi, ok = evaluate(P, cand, lv)
            xi_f, ok_f = evaluate(F, np.zeros(P.n_agents, dtype=np.int64), lv)
            assert xi_f == pytest.approx(float(xi), abs=1e-15) and bool(ok_f) == bool(ok)


def test_exact_closes_in_where_every_plan_is_worth_nothing(antenna):
    for P in _traps(antenna, 4):
        plain, = _search(P)
        closed, = _search(P, close_in=THRESHOLD)
        sol, value = closed
        free = solve(replace(P, constraints=False), "exact", [], time_limit_s=None)
        assert sol.closed_in and sol.feasible and not sol.optimal
        assert np.array_equal(sol.move, free.move)  # the moves of the plan without Eq. (13)
        cand = P.slots_of(sol.move)
        assert value == pytest.approx(_best_levels(P, cand), abs=1e-12)  # the best levels there
        xi, ok = evaluate(P, cand, sol.level)
        assert ok and float(xi) == pytest.approx(value, abs=1e-12)
        assert value <= plain[1] + 1e-12  # it gives up Xi for closeness: the constrained optimum is the most
        assert not np.array_equal(sol.move, plain[0].move)


def test_a_plan_worth_the_threshold_is_kept(antenna):
    rng = np.random.default_rng(11)
    kept = 0
    for _ in range(30):
        P = random_problem(rng, antenna, spread=6.0)
        (plain, v0), = _search(P)
        (sol, v1), = _search(P, close_in=THRESHOLD)
        if v0 >= THRESHOLD:
            kept += 1
            assert not sol.closed_in and v1 == v0 and np.array_equal(sol.move, plain.move)
            assert np.array_equal(sol.level, plain.level)
    assert kept >= 10


def test_every_searcher_of_one_problem_gets_the_same_closed_plan(antenna):
    P = _traps(antenna, 1)[0]
    found = _search(P, close_in=THRESHOLD, rows=(0, 1, 2))
    assert len(found) == 3
    for sol, value in found:
        assert sol.closed_in and np.array_equal(sol.move, found[0][0].move)
        assert np.array_equal(sol.level, found[0][0].level) and value == found[0][1]


def test_grasp_closes_in_too(antenna):
    """GRASP on small instances (7 controls): each searcher's plan is feasible, moves every agent
    as the optimum without Eq. (13) does (in value) and transmits at the best levels there."""
    for P in _traps(antenna, 3, displacements=tiny_displacements(), spread=25.0):
        free = solve(replace(P, constraints=False), "exact", [], time_limit_s=None)
        for sol, value in _search(P, "grasp", close_in=THRESHOLD, rows=(0, 1, 2)):
            assert sol.closed_in and sol.feasible
            cand = P.slots_of(sol.move)
            top = np.full(P.n_agents, P.n_levels - 1)
            free_value, _ = evaluate(replace(P, constraints=False), cand, top)
            assert float(free_value) == pytest.approx(free.objective, abs=1e-12)
            assert value == pytest.approx(_best_levels(P, cand), abs=1e-12)


def test_guarded_agents_stay_at_hover_and_are_not_jammed(antenna):
    """An agent the planner did not hear from this step (a guard: hovering, adding nothing to Xi,
    still a receiver of Eq. 13) stays at hover when the team closes in, and is not jammed."""
    closed = 0
    for P in _traps(antenna, 6):
        G = P.guarded(2)
        (sol, _), = _search(G, close_in=1.0)  # every plan is below 1: closes in unless the moves agree
        assert sol.feasible and sol.move[2] == 0
        closed += sol.closed_in
    assert closed >= 2


def test_a_searcher_whose_budget_is_spent_keeps_its_plan(antenna):
    """`control.time_limit_s` is the budget of the step's three solves: spent by the first, the
    searcher does not close in."""
    P = _traps(antenna, 1)[0]
    (sol, _), = own_searches(P, "exact", [0], [np.random.default_rng(0)], 2000, 20, 4, 1, 1e-12, 0, 1.0)
    assert not sol.closed_in
    (sol, _), = own_searches(P, "exact", [0], [np.random.default_rng(0)], 2000, 20, 4, 1, 10.0, 0, 1.0)
    assert sol.closed_in


def test_grasp_closes_in_whatever_its_own_search_took(antenna):
    """`control.time_limit_s` bounds `exact`, not GRASP: a GRASP searcher still closes in after a
    search longer than the budget, the levels' exact solve getting the budget to itself."""
    P = _traps(antenna, 1, displacements=tiny_displacements(), spread=25.0)[0]
    (sol, _), = own_searches(P, "grasp", [0], [np.random.default_rng(0)], 2000, 20, 4, 1, 1e-12, 0, 1.0)
    assert sol.closed_in


def test_a_plan_that_already_moves_as_the_unconstrained_one_stands(antenna):
    """Below the threshold, but the optimum without Eq. (13) moves every agent as the plan does
    (far from the aim every move is worth Xi = 0, and both hover): the plan stands, still
    proven optimal, not marked closed in."""
    rng = np.random.default_rng(5)
    same = 0
    for _ in range(60):
        P = random_problem(rng, antenna, spread=40.0)
        (plain, v0), = _search(P)
        free = solve(replace(P, constraints=False), "exact", [], time_limit_s=None)
        if v0 < THRESHOLD and np.array_equal(free.move, plain.move):
            same += 1
            (sol, v1), = _search(P, close_in=THRESHOLD)
            assert not sol.closed_in and sol.optimal and v1 == v0 and np.array_equal(sol.level, plain.level)
    assert same >= 3
