"""Planning over the belief: Eq. (12)'s objective averaged over weighted samples of the target's
position, every cone still aimed at x_bar; one sample at x_bar is the point objective, bit for
bit, and every solver optimises the same average."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.exact import enumerate_optimum, kernel_mean_xi, solve_exact
from trackjam.control.grasp import solve_grasp
from trackjam.control.greedy import solve_greedy
from trackjam.control.objective import at_least_probability, evaluate, mean_at_least
from trackjam.control.problem import build_problem
from trackjam.radio.antenna import detection_probability

from control_instances import HIGH, LOW, assert_grasp_kernel_follows_its_twin, small_displacements, tiny_displacements


def belief_problem(rng, antenna, n_agents=3, at_least=2, constraints=True, S=8, spread=8.0,
                   displacements=None, sample_std=3.0):
    D = tiny_displacements() if displacements is None else displacements
    x = rng.uniform(10, 90, 3)
    u = np.clip(x + rng.normal(0, spread, (n_agents, 3)), 0, 100)
    xs = x + rng.normal(0, sample_std, (S, 3))
    w = rng.uniform(0.1, 1.0, S)
    point = build_problem(u, x, D, antenna, LOW, HIGH, at_least, constraints)
    belief = build_problem(u, x, D, antenna, LOW, HIGH, at_least, constraints, samples=xs, weights=w)
    return point, belief


def slots(P, sol):
    return np.array([int(np.flatnonzero(P.move[i] == sol.move[i])[0]) for i in range(P.n_agents)])


def test_one_sample_at_x_bar_is_the_point_objective_bit_for_bit(antenna):
    rng = np.random.default_rng(0)
    for trial in range(6):
        x = rng.uniform(10, 90, 3)
        u = np.clip(x + rng.normal(0, 7, (3, 3)), 0, 100)
        D = small_displacements()
        args = (u, x, D, antenna, LOW, HIGH, 1 + trial % 3, trial % 2 == 0)
        point = build_problem(*args)
        one = build_problem(*args, samples=[x], weights=[0.3])
        assert one.weights[0] == 1.0 and np.array_equal(one.p_d_samples[0], point.p_d)
        rngs = lambda: [np.random.default_rng([trial, j]) for j in range(3)]  # noqa: E731
        pairs = [
            (solve_exact(point), solve_exact(one)),
            (solve_greedy(point), solve_greedy(one)),
            (solve_grasp(point, rngs(), samples=300, iterations=8), solve_grasp(one, rngs(), samples=300, iterations=8)),
        ]
        for a, b in pairs:
            assert np.array_equal(a.move, b.move) and np.array_equal(a.level, b.level)
            assert a.objective == b.objective and a.feasible == b.feasible


def test_the_objective_is_the_weighted_mean_of_xi_at_the_samples(antenna):
    rng = np.random.default_rng(1)
    point, P = belief_problem(rng, antenna, S=5)
    for _ in range(20):
        cand = np.array([rng.integers(P.n_cand[i]) for i in range(3)])
        level = rng.integers(0, P.n_levels, 3)
        pos = P.cand_pos[np.arange(3), cand]
        expected = 0.0
        for x_s, w_s in zip(P.samples, P.weights):
            p = [detection_probability(x_s, pos[i], P.aim, P.levels_w[level[i]], antenna) for i in range(3)]
            expected += w_s * float(at_least_probability(np.array(p), P.at_least))
        xi, ok = evaluate(P, cand, level)
        assert float(xi) == pytest.approx(expected, rel=1e-12, abs=1e-15)
        assert ok == evaluate(point, cand, level)[1]  # Eq. (13) does not depend on the samples
    assert np.isclose(P.weights.sum(), 1.0)


def test_the_compiled_mean_is_the_numpy_mean_bit_for_bit():
    rng = np.random.default_rng(2)
    for S in (1, 3, 16):
        w = rng.uniform(0, 1, S)
        w /= w.sum()
        for n in (1, 2, 3):
            p = rng.uniform(0, 1, (S, 4))
            assert kernel_mean_xi(p, w, n, np.empty(n + 1)) == float(mean_at_least(p, w, n))


def test_the_mean_over_samples_is_the_per_sample_sum_bit_for_bit():
    """mean_at_least's one programme over all samples is the sample-by-sample sum it replaced,
    for plans (S, N) and for batches of plans (S, M, N), n = 0 and n > N included."""
    rng = np.random.default_rng(3)
    for S in (1, 5, 48):
        w = rng.uniform(0, 1, S)
        w /= w.sum()
        for shape in ((S, 3), (S, 7, 3)):
            p = rng.uniform(0, 1, shape)
            for n in (0, 1, 2, 3, 4):
                acc = 0.0
                for s in range(S):
                    acc = acc + w[s] * at_least_probability(p[s], n)
                assert np.array_equal(mean_at_least(p, w, n), np.asarray(acc))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 3), st.integers(1, 3), st.booleans(), st.integers(2, 6))
def test_exact_is_the_optimum_of_the_averaged_objective(antenna, seed, n_agents, at_least, constraints, S):
    rng = np.random.default_rng(seed)
    _, P = belief_problem(rng, antenna, n_agents, min(at_least, n_agents), constraints, S=S,
                          spread=rng.uniform(3, 10), sample_std=rng.uniform(0.5, 6))
    value, cand, level = enumerate_optimum(P)
    sol = solve_exact(P)
    assert sol.optimal and sol.gap == 0.0
    assert sol.objective == pytest.approx(value, rel=1e-12, abs=1e-15)
    assert np.array_equal(sol.move, P.move[np.arange(n_agents), cand]) and np.array_equal(sol.level, level)
    capped = solve_exact(P, node_limit=3)
    assert capped.objective + capped.gap >= value - 1e-12
    xi, ok = evaluate(P, slots(P, capped), capped.level)
    assert capped.objective == float(xi) and (ok or not constraints)


def test_grasp_kernel_follows_its_numpy_twin_on_the_belief(antenna):
    rng = np.random.default_rng(5)
    for trial in range(4):
        _, P = belief_problem(rng, antenna, 3, 1 + trial % 3, trial % 2 == 0, S=4,
                              displacements=small_displacements())
        assert_grasp_kernel_follows_its_twin(P, trial, 200, 10)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_grasp_on_the_belief_is_feasible_and_never_beats_exact(antenna, seed, constraints):
    rng = np.random.default_rng(seed)
    _, P = belief_problem(rng, antenna, 3, 2, constraints, S=6)
    g = solve_grasp(P, [np.random.default_rng([seed, j]) for j in range(3)], samples=300, iterations=5)
    assert g.objective <= solve_exact(P).objective + 1e-12
    assert g.feasible or not constraints
    assert g.objective == float(evaluate(P, slots(P, g), g.level)[0])


def test_greedy_on_the_belief_maximises_each_agents_mean_p_d(antenna):
    rng = np.random.default_rng(7)
    for _ in range(5):
        _, P = belief_problem(rng, antenna, 3, 2, True, S=6, displacements=small_displacements())
        sol = solve_greedy(P)
        mean_p = np.tensordot(P.weights, P.p_d_samples, axes=1)
        for i in range(3):
            n = P.n_cand[i]
            c = slots(P, sol)[i]
            assert mean_p[i, c, sol.level[i]] == pytest.approx(mean_p[i, :n].max(), rel=1e-12, abs=1e-15)


def test_guarded_rows_add_nothing_at_any_sample(antenna):
    _, P = belief_problem(np.random.default_rng(9), antenna, 3, 1, True, S=4)
    G = P.guarded(2)
    assert G.n_cand[2] == 1 and np.all(G.p_d[2] == 0) and np.all(G.p_d_samples[:, 2] == 0)
    assert np.array_equal(G.p_d_samples[:, :2], P.p_d_samples[:, :2])


@pytest.mark.parametrize("samples, weights", [
    (np.zeros((0, 3)), None), (np.zeros((2, 2)), None), ([[np.nan, 0, 0]], None),
    ([[1.0, 2, 3], [4, 5, 6]], [1.0]), ([[1.0, 2, 3]], [-1.0]), ([[1.0, 2, 3], [4, 5, 6]], [0.0, 0.0]),
])
def test_bad_samples_or_weights_are_refused(antenna, samples, weights):
    with pytest.raises(ValueError):
        build_problem([[50.0, 50, 50]], [55.0, 50, 50], tiny_displacements(), antenna, LOW, HIGH, 1, True,
                      samples=samples, weights=weights)
