"""The K-target decision: its objective (closed forms, the compiled twin, Eq. 12 at K = 1), the
exact solver against full enumeration, and every solver at K = 1 against today's solver."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.assignment import (
    ASSIGNMENT_SOLVERS,
    SolverOptions,
    build_assignment,
    solve_assignment,
)
from trackjam.control.assignment_exact import agent_order, solve_assignment_exact
from trackjam.control.assignment_problem import (
    assignment_value,
    kernel_targets_value,
    kernel_targets_value_unrolled,
    target_xi,
)
from trackjam.control.exact import pair_order, solve_exact
from trackjam.control.objective import at_least_probability, evaluate
from trackjam.control.solve import SOLVERS, solve

from control_instances import HIGH, LOW, small_displacements, tiny_displacements


def random_assignment(rng, antenna, n_agents=3, n_targets=2, at_least=2, constraints=True, objective="sum",
                      displacements=None, spread=8.0):
    """Agents and K aims scattered around a centre (a small swarm)."""
    D = tiny_displacements() if displacements is None else displacements
    x = rng.uniform(5, 95, 3)
    aims = np.clip(x + rng.normal(0, spread, (n_targets, 3)), 0, 100)
    u = np.clip(x + rng.normal(0, spread, (n_agents, 3)), 0, 100)
    return build_assignment(u, aims, D, antenna, LOW, HIGH, at_least, constraints, objective)


def enumerate_assignment(problem) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Plain-numpy enumeration of every (candidate, level, target) of every agent, in the
    search's order (small instances only, agents in :func:`agent_order`): (value, candidate
    slots, levels, targets), with the search's starting incumbent and ties."""
    N, K, L = problem.n_agents, problem.n_targets, problem.n_levels
    orders = [pair_order(P)[0] for P in problem.targets]
    tgt, prs = [], []  # each agent's choices in the search's order: target blocks, pair ranks
    for i in range(N):
        b = int(problem.n_cand[i]) * L
        tgt.append(np.repeat(np.arange(K), b))
        prs.append(np.concatenate([orders[k][i, :b] for k in range(K)]))
    first = agent_order(problem)  # the slowest-varying agent first
    grids = np.meshgrid(*[np.arange(len(tgt[i])) for i in first], indexing="ij")
    idx = np.empty((grids[0].size, N), dtype=np.int64)
    for d, i in enumerate(first):
        idx[:, i] = grids[d].ravel()
    target = np.stack([tgt[i][idx[:, i]] for i in range(N)], axis=-1)
    pair = np.stack([prs[i][idx[:, i]] for i in range(N)], axis=-1)
    value, ok = assignment_value(problem, pair // L, pair % L, target)
    if problem.constraints:
        value = np.where(ok, value, -np.inf)
    z = np.zeros(N, dtype=np.int64)
    v0, ok0 = assignment_value(problem, z, z, z)
    start = float(v0) if (ok0 or not problem.constraints) else -np.inf
    s = int(np.argmax(value))
    if value[s] > start:
        return float(value[s]), pair[s] // L, pair[s] % L, target[s]
    return start, z, z, z


def random_choices(rng, P, rows):
    N, L, K = P.n_agents, P.n_levels, P.n_targets
    cand = np.stack([rng.integers(0, P.n_cand[i], rows) for i in range(N)], axis=-1)
    return cand, rng.integers(0, L, (rows, N)), rng.integers(0, K, (rows, N))


def slots(P, sol):
    move = P.targets[0].move
    return np.array([int(np.flatnonzero(move[i] == sol.move[i])[0]) for i in range(P.n_agents)])


def test_xi_per_target_is_the_closed_form(antenna):
    """n_k = min(n, m_k): two servers with n = 2 must both detect, one alone must detect, a
    target nobody serves is worth 0; sum and min combine them."""
    rng = np.random.default_rng(1)
    for objective in ("sum", "min"):
        P = random_assignment(rng, antenna, 3, 3, 2, True, objective)
        cand, level = np.array([1, 2, 0]), np.array([3, 2, 3])
        p = [P.targets[k].p_d[i, cand[i], level[i]] for i, k in enumerate([0, 0, 1])]
        xi = target_xi(P, cand, level, [0, 0, 1])
        assert np.allclose(xi, [p[0] * p[1], p[2], 0.0], rtol=1e-14, atol=0)
        value, _ = assignment_value(P, cand, level, [0, 0, 1])
        assert value == pytest.approx(p[0] * p[1] + p[2] if objective == "sum" else 0.0, rel=1e-14)
        p3 = [P.targets[0].p_d[i, cand[i], level[i]] for i in range(3)]
        two_of_three = p3[0] * p3[1] + p3[0] * p3[2] + p3[1] * p3[2] - 2 * p3[0] * p3[1] * p3[2]
        assert target_xi(P, cand, level, [0, 0, 0])[0] == pytest.approx(two_of_three, rel=1e-12)


@pytest.mark.parametrize("objective", ["sum", "min"])
def test_compiled_objective_is_its_numpy_twin_bit_for_bit(antenna, objective):
    rng = np.random.default_rng(2)
    for K in (1, 2, 3):
        P = random_assignment(rng, antenna, 4, K, 2, True, objective, small_displacements())
        cand, level, target = random_choices(rng, P, 200)
        ref, _ = assignment_value(P, cand, level, target)
        N, L = P.n_agents, P.n_levels
        kk, p, q = np.empty(N, dtype=np.int64), np.empty(N), np.empty(P.at_least + 1)
        for r in range(200):
            v = kernel_targets_value(P.pz, P.at_least, P.kind, cand[r] * L + level[r], target[r], kk, p, q)
            assert v == ref[r]


@pytest.mark.parametrize("objective", ["sum", "min"])
@pytest.mark.parametrize("at_least", [1, 2, 3])
def test_the_unrolled_objective_is_the_compiled_one_bit_for_bit(antenna, objective, at_least):
    """kernel_targets_value_unrolled, which GRASP's hot loop calls for n <= 3, equals
    kernel_targets_value on every choice, one to three targets (n above the agents a target
    has included)."""
    rng = np.random.default_rng(at_least)
    for K in (1, 2, 3):
        for N in (2, 4):
            P = random_assignment(rng, antenna, N, K, min(at_least, N), True, objective, small_displacements())
            cand, level, target = random_choices(rng, P, 100)
            kk, p, q = np.empty(N, dtype=np.int64), np.empty(N), np.empty(P.at_least + 1)
            for r in range(100):
                pair = cand[r] * P.n_levels + level[r]
                v = kernel_targets_value(P.pz, P.at_least, P.kind, pair, target[r], kk, p, q)
                assert kernel_targets_value_unrolled(P.pz, P.at_least, P.kind, pair, target[r], kk) == v


@pytest.mark.parametrize("objective", ["sum", "min"])
def test_one_target_is_eq12_bit_for_bit(antenna, objective):
    rng = np.random.default_rng(3)
    P = random_assignment(rng, antenna, 4, 1, 3, True, objective, small_displacements())
    cand, level, target = random_choices(rng, P, 300)
    value, ok = assignment_value(P, cand, level, target)
    xi, ok1 = evaluate(P.targets[0], cand, level)
    assert np.array_equal(value, xi) and np.array_equal(ok, ok1)


def test_interference_follows_the_served_target(antenna):
    """Eq. (13) checks each sender's cone aimed at the target it serves: the extended gain
    table is the one-target table of that aim."""
    rng = np.random.default_rng(4)
    P = random_assignment(rng, antenna, 3, 2, 2, True, "sum", small_displacements())
    C = P.n_slots
    for i, j, ci, cj, ki, kj in rng.integers(0, [3, 3, 5, 5, 2, 2], (200, 6)):
        assert P.gain[i, j, ki * C + ci, kj * C + cj] == P.targets[kj].gain[i, j, ci, cj]


@pytest.mark.parametrize("n_agents,n_targets", [(1, 2), (1, 3), (2, 2), (2, 3), (3, 2)])  # N = 1 too
@pytest.mark.parametrize("objective", ["sum", "min"])
@pytest.mark.parametrize("constraints", [True, False])
def test_exact_equals_full_enumeration(antenna, n_agents, n_targets, objective, constraints):
    rng = np.random.default_rng(100 * n_agents + 10 * n_targets + constraints)
    for trial in range(4):
        at_least = 1 + trial % n_agents
        P = random_assignment(rng, antenna, n_agents, n_targets, at_least, constraints, objective,
                              spread=5.0 + 2 * trial)
        value, cand, level, target = enumerate_assignment(P)
        sol = solve_assignment_exact(P)
        assert sol.objective == value
        assert np.array_equal(slots(P, sol), cand) and np.array_equal(sol.level, level)
        assert np.array_equal(sol.target, target)
        assert sol.optimal and sol.gap == 0.0 and sol.nodes > 0
        assert sol.feasible or not constraints


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 3), st.sampled_from(["sum", "min"]),
       st.sampled_from([1, 3, 10, 50]))
def test_a_stopped_search_certifies_its_gap(antenna, seed, n_agents, objective, node_limit):
    rng = np.random.default_rng(seed)
    P = random_assignment(rng, antenna, n_agents, 2, 1 + seed % n_agents, True, objective,
                          spread=rng.uniform(3, 12))
    optimum = enumerate_assignment(P)[0]
    sol = solve_assignment_exact(P, node_limit=node_limit)
    assert sol.nodes <= node_limit and sol.feasible
    assert sol.objective <= optimum and sol.objective + sol.gap >= optimum - 1e-12
    if sol.optimal:
        assert sol.gap == 0.0 and sol.objective == optimum


@pytest.mark.parametrize("n_agents", [3, 4])
@pytest.mark.parametrize("objective", ["sum", "min"])
def test_one_target_gives_todays_decision_for_every_solver(antenna, n_agents, objective):
    rng = np.random.default_rng(20 + n_agents)
    options = SolverOptions(samples=300, iterations=6, neighbours=4, time_limit_s=None)
    for trial in range(5):
        P = random_assignment(rng, antenna, n_agents, 1, 1 + trial % n_agents, trial % 3 != 0, objective,
                              small_displacements(), spread=6.0 + trial)
        for name in ASSIGNMENT_SOLVERS:
            mine = solve_assignment(P, name, [np.random.default_rng([trial, j]) for j in range(n_agents)], options)
            today = solve(P.targets[0], name, [np.random.default_rng([trial, j]) for j in range(n_agents)],
                          samples=300, iterations=6, neighbours=4, time_limit_s=None)
            assert np.array_equal(mine.move, today.move) and np.array_equal(mine.level, today.level), name
            assert mine.objective == today.objective and mine.feasible == today.feasible
            assert not mine.target.any() and mine.xi.tolist() == [today.objective]


def test_exact_one_target_equals_exact_on_paper_sized_problems(antenna):
    """79 controls, N = 3: the K = 1 search is today's search, plan for plan."""
    from trackjam.world.moves import displacement_set

    rng = np.random.default_rng(5)
    D = displacement_set([1.0, 3.0, 5.0], 8, 8)
    for trial in range(6):
        P = random_assignment(rng, antenna, 3, 1, 2, True, "sum", D, spread=10.0)
        mine, today = solve_assignment_exact(P), solve_exact(P.targets[0])
        assert np.array_equal(mine.move, today.move) and np.array_equal(mine.level, today.level)
        assert mine.objective == today.objective and mine.optimal and today.optimal


def test_registry_repeats_the_one_target_names_and_refuses_unknown_ones(antenna):
    assert set(ASSIGNMENT_SOLVERS) == set(SOLVERS)
    P = random_assignment(np.random.default_rng(6), antenna, 2, 2, 1)
    with pytest.raises(ValueError, match="unknown solver"):
        solve_assignment(P, "nope", [])


@pytest.mark.parametrize("name, fn, error, words", [
    (["a"], lambda p, r, o: None, ValueError, "register_assignment: a solver's name must be a non-empty text"),
    ("", lambda p, r, o: None, ValueError, "register_assignment: a solver's name must be a non-empty text"),
    ("five-test", 5, TypeError, "register_assignment('five-test'): expected a function"),
])
def test_register_assignment_refuses_what_is_not_a_named_function(name, fn, error, words):
    # as register does a one-target solver: all were taken (a list as "unhashable type"), and a
    # number failed at the swarm engine's first plan
    from trackjam.control.assignment import register_assignment

    before = dict(ASSIGNMENT_SOLVERS)
    with pytest.raises(error) as err:
        register_assignment(name)(fn)
    assert str(err.value).startswith(words) and ASSIGNMENT_SOLVERS == before


def test_an_assignment_solver_that_returns_no_solution_is_named(antenna):
    from trackjam.control.assignment import register_assignment

    P = random_assignment(np.random.default_rng(6), antenna, 2, 2, 1)
    register_assignment("none-test")(lambda problem, rngs, options: None)
    try:
        with pytest.raises(TypeError, match="^assignment solver 'none-test' returned NoneType, not an AssignmentSolution$"):
            solve_assignment(P, "none-test", [])
    finally:
        del ASSIGNMENT_SOLVERS["none-test"]


def test_bad_problems_are_refused(antenna):
    u, D = np.full((2, 3), 50.0), tiny_displacements()
    with pytest.raises(ValueError, match="objective"):
        build_assignment(u, [[40.0, 40, 40]], D, antenna, LOW, HIGH, 1, True, "max")
    with pytest.raises(ValueError, match="aims"):
        build_assignment(u, np.zeros((0, 3)), D, antenna, LOW, HIGH, 1, True)
    with pytest.raises(ValueError, match="aims"):
        build_assignment(u, [[np.nan, 1, 1]], D, antenna, LOW, HIGH, 1, True)
    with pytest.raises(ValueError, match="at_least"):
        build_assignment(u, [[40.0, 40, 40]], D, antenna, LOW, HIGH, 3, True)


def test_greedy_takes_each_agents_best_pd_over_every_target(antenna):
    rng = np.random.default_rng(11)
    for trial in range(5):
        P = random_assignment(rng, antenna, 3, 3, 2, True, "sum", small_displacements())
        sol = solve_assignment(P, "greedy", [])
        for i in range(P.n_agents):
            n = P.n_cand[i]
            best = max(P.targets[k].p_d[i, :n].max() for k in range(P.n_targets))
            assert P.targets[sol.target[i]].p_d[i, slots(P, sol)[i], sol.level[i]] == best


def test_agents_are_placed_by_what_they_add_to_the_targets_coverage(antenna):
    rng = np.random.default_rng(12)
    P1 = random_assignment(rng, antenna, 4, 1, 2)
    assert agent_order(P1).tolist() == [0, 1, 2, 3]
    for trial in range(5):
        P = random_assignment(rng, antenna, 4, 2, 2, spread=10.0)
        order = agent_order(P)
        best = P.pz.max(axis=2).T  # (N, K)
        assert sorted(order.tolist()) == [0, 1, 2, 3]
        assert best[order[0]].max() == best.max()
        miss = 1.0 - best[order[0]]
        assert (best[order[1]] * miss).max() == max((best[j] * miss).max() for j in order[1:])


@pytest.mark.parametrize("objective", ["sum", "min"])
def test_exact_without_the_constraints_equals_the_best_split_of_the_agents(antenna, objective):
    """Larger teams than the enumeration reaches (N = 4-5, K = 2-4): without Eq. (13) each agent
    serving k takes its best p_D at x_bar_k (Xi_k rises with every p_D at a fixed split), so the
    optimum is the best over the K^N splits of the agents of sum or min_k Xi_k, n_k = min(n, m_k),
    computed here from the closed form at_least_probability."""
    rng = np.random.default_rng(17 if objective == "sum" else 18)
    for trial in range(6):
        N, K, n = 4 + trial % 2, 2 + trial % 3, 1 + trial % 2
        P = random_assignment(rng, antenna, N, K, n, False, objective, small_displacements(), spread=8.0)
        best = np.array([t.p_d.reshape(N, -1).max(axis=1) for t in P.targets])  # (K, N)
        optimum = 0.0
        for split in itertools.product(range(K), repeat=N):
            split = np.array(split)
            xi = [float(at_least_probability(best[k][split == k], min(n, int((split == k).sum()))))
                  if (split == k).any() else 0.0 for k in range(K)]
            optimum = max(optimum, sum(xi) if objective == "sum" else min(xi))
        sol = solve_assignment_exact(P)
        assert sol.optimal and sol.objective == pytest.approx(optimum, abs=1e-12)
