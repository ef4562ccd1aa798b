"""The LMB update's data association: Gibbs sampling and Murty's ranked assignment against the
enumeration of every joint hypothesis on small cases."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from trackjam.estimation.lmb_association import (
    LOG_FLOOR,
    association_marginals,
    best_hypothesis,
    gibbs_hypotheses,
    hypothesis_log_weights,
    kernel_gibbs,
    marginals,
    ranked_hypotheses,
    unique_rows,
)


def all_hypotheses(T: int, m: int) -> np.ndarray:
    """Every joint hypothesis: each track undetected (0) or on a measurement (1 + j), no
    measurement used twice."""
    out = [g for g in itertools.product(range(m + 1), repeat=T)
           if len([c for c in g if c > 0]) == len({c for c in g if c > 0})]
    return np.array(out, dtype=np.int64).reshape(-1, T)


def brute_force_marginals(log_eta: np.ndarray) -> np.ndarray:
    T, m1 = log_eta.shape
    hyps = all_hypotheses(T, m1 - 1)
    w = np.exp([sum(log_eta[i, g[i]] for i in range(T)) for g in hyps])
    w /= w.sum()
    beta = np.zeros((T, m1))
    for g, wg in zip(hyps, w):
        for i in range(T):
            beta[i, g[i]] += wg
    return beta


def gibbs_twin(log_eta, start, uniforms):
    """Plain-numpy twin of ``kernel_gibbs``."""
    S, T = uniforms.shape
    g = start.copy()
    out = np.empty((S, T), dtype=np.int64)
    for s in range(S):
        for i in range(T):
            taken = {c for k, c in enumerate(g) if k != i and c > 0}
            allowed = np.array([c == 0 or c not in taken for c in range(log_eta.shape[1])])
            p = np.where(allowed, np.exp(log_eta[i] - log_eta[i][allowed].max()), 0.0)
            cum = np.cumsum(p)
            pos = np.flatnonzero(uniforms[s, i] * cum[-1] < cum)
            g[i] = pos[0] if len(pos) else np.flatnonzero(p > 0)[-1]
        out[s] = g
    return out


def log_eta_strategy(max_tracks=2, max_meas=3):
    shapes = st.tuples(st.integers(1, max_tracks), st.integers(0, max_meas)).map(lambda tm: (tm[0], tm[1] + 1))
    return shapes.flatmap(lambda shape: arrays(float, shape, elements=st.floats(-4.0, 4.0)))


@settings(max_examples=40, deadline=None)
@given(log_eta_strategy(), st.integers(0, 2**32 - 1))
def test_gibbs_kernel_equals_numpy_twin(log_eta, seed):
    rng = np.random.default_rng(seed)
    start = best_hypothesis(log_eta)
    U = rng.random((30, log_eta.shape[0]))
    np.testing.assert_array_equal(kernel_gibbs(log_eta, start, U), gibbs_twin(log_eta, start, U))


@settings(max_examples=40, deadline=None)
@given(log_eta_strategy(2, 3))
def test_ranked_with_k_all_equals_enumeration_exactly(log_eta):
    T, m1 = log_eta.shape
    n_all = len(all_hypotheses(T, m1 - 1))
    hyps = ranked_hypotheses(log_eta, k=10_000)
    assert len(hyps) == n_all == len(np.unique(hyps, axis=0))
    np.testing.assert_allclose(marginals(log_eta, hyps), brute_force_marginals(log_eta), rtol=0, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(log_eta_strategy(3, 3), st.integers(1, 6))
def test_ranked_gives_the_k_best_in_order(log_eta, k):
    T, m1 = log_eta.shape
    every = all_hypotheses(T, m1 - 1)
    w_all = np.sort(hypothesis_log_weights(log_eta, every))[::-1]
    hyps = ranked_hypotheses(log_eta, k)
    w = hypothesis_log_weights(log_eta, hyps)
    assert len(hyps) == min(k, len(every))
    np.testing.assert_allclose(w, w_all[: len(hyps)], atol=1e-9)
    if len(w_all) < 2 or w_all[0] - w_all[1] > 1e-9:  # a unique best
        np.testing.assert_array_equal(best_hypothesis(log_eta), hyps[0])


@settings(max_examples=30, deadline=None)
@given(log_eta_strategy(2, 3), st.integers(0, 2**32 - 1))
def test_gibbs_marginals_equal_enumeration(log_eta, seed):
    """The distinct hypotheses visited, each with its exact weight: the best one is always among
    them, and the marginals differ from the enumeration's by at most twice the weight of the
    hypotheses never visited (a bound that holds whatever was visited: at most that weight).
    That 1000 sweeps visit every hypothesis of 1 % or more is not true in general: with
    log_eta = [[-1, 1, 0], [-3, 4, -1]] the hypothesis (1, 2) holds 1.3 % of the weight but is
    reached from the two that hold 98 % only through a step of probability 0.7 %, and about one
    seed in nine never visits it (34 of the seeds 0-299, 109 among them)."""
    visited = gibbs_hypotheses(log_eta, 1000, np.random.default_rng(seed))
    every = all_hypotheses(log_eta.shape[0], log_eta.shape[1] - 1)
    p = np.exp(hypothesis_log_weights(log_eta, every))
    p /= p.sum()
    seen = np.array([any(np.array_equal(g, v) for v in visited) for g in every])
    assert np.any(seen[p >= p.max() * (1 - 1e-9)])
    beta = association_marginals(log_eta, "gibbs", np.random.default_rng(seed), samples=1000)
    assert np.abs(beta - brute_force_marginals(log_eta)).max() <= 2 * p[~seen].sum() + 1e-12


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 40), st.integers(0, 6), st.integers(1, 4))
def test_unique_rows_is_numpys_unique(seed, H, T, values):
    a = np.random.default_rng(seed).integers(0, values, size=(H, T))
    np.testing.assert_array_equal(unique_rows(a), np.unique(a, axis=0))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gibbs_visits_hypotheses_in_proportion_to_their_weight(seed):
    """The sampler's stationary distribution is the hypotheses' normalised weights: the share of
    sweeps on each hypothesis matches it within Monte Carlo error."""
    rng = np.random.default_rng(seed)
    log_eta = rng.uniform(-1.5, 1.5, size=(2, 4))
    every = all_hypotheses(2, 3)
    p = np.exp(hypothesis_log_weights(log_eta, every))
    p /= p.sum()
    S = 20_000
    drawn = kernel_gibbs(log_eta, best_hypothesis(log_eta), rng.random((S, 2)))
    freq = np.array([np.mean(np.all(drawn == g, axis=1)) for g in every])
    # consecutive sweeps are correlated: allow a few times the independent standard error
    assert np.all(np.abs(freq - p) < 6 * np.sqrt(p * (1 - p) / S) + 2e-3)


def test_forbidden_and_certain_entries():
    """eta = 0 (log -inf) is never chosen; a track certain to be detected still has an
    undetected hypothesis (the floor), so the marginals stay defined."""
    log_eta = np.array([[-np.inf, 0.0, -np.inf], [0.0, -np.inf, 1.0]])
    for method in ("gibbs", "ranked"):
        beta = association_marginals(log_eta, method, np.random.default_rng(0), samples=200)
        assert beta[0, 1] == pytest.approx(1.0)
        assert beta[0, 2] == 0.0 and beta[1, 1] == 0.0
        np.testing.assert_allclose(beta.sum(axis=1), 1.0)
    assert association_marginals(np.zeros((0, 3)), "gibbs", np.random.default_rng(0)).shape == (0, 3)
    with pytest.raises(ValueError, match="association method"):
        association_marginals(log_eta, "all", np.random.default_rng(0))


def test_many_tracks_scale_without_enumeration():
    """20 tracks and 15 measurements have more than 10^23 hypotheses; both methods answer, the
    most likely hypothesis is among the ranked ones first, and every row sums to 1."""
    rng = np.random.default_rng(5)
    log_eta = rng.normal(0.0, 2.0, size=(20, 16))
    ranked = ranked_hypotheses(log_eta, 30)
    assert len(np.unique(ranked, axis=0)) == 30
    np.testing.assert_array_equal(ranked[0], best_hypothesis(log_eta))
    w = hypothesis_log_weights(log_eta, ranked)
    assert np.all(np.diff(w) <= 1e-9)
    hyps = gibbs_hypotheses(log_eta, 500, rng)
    assert any(np.array_equal(h, ranked[0]) for h in hyps)
    assert hypothesis_log_weights(log_eta, hyps).max() == pytest.approx(w[0])
    for method in ("gibbs", "ranked"):
        beta = association_marginals(log_eta, method, rng, samples=500, k=30)
        np.testing.assert_allclose(beta.sum(axis=1), 1.0)
        assert np.all(beta[:, 1:].sum(axis=0) <= 1.0 + 1e-9)  # a measurement is some track's at most once


def test_with_misses_a_confident_detection_leaves_the_miss_its_weight():
    """One track, one confident detection: the miss holds about e^-7 of the weight, and Gibbs,
    started at the detection, may never visit it, so beta_0 = 0 and the track's existence
    becomes exactly 1. With ``misses`` the best hypothesis's miss is weighed for each track."""
    log_eta = np.array([[-7.0, 0.0, -9.0], [-6.0, -8.0, 0.5]])
    exact = brute_force_marginals(log_eta)
    plain = [association_marginals(log_eta, "gibbs", np.random.default_rng(s), samples=50) for s in range(20)]
    assert any(b[0, 0] == 0.0 for b in plain)  # the flaw the option mends: some seeds never visit a miss
    for s in range(20):
        beta = association_marginals(log_eta, "gibbs", np.random.default_rng(s), samples=50, misses=True)
        assert np.all(beta[:, 0] > 0)
        np.testing.assert_allclose(beta[:, 0], exact[:, 0], rtol=0.05)


@settings(max_examples=60, deadline=None)
@given(log_eta_strategy(3, 3), st.integers(0, 2**32 - 1))
def test_with_misses_gibbs_keeps_every_hypothesis_it_visited_and_adds_only_real_ones(log_eta, seed):
    T, m = log_eta.shape[0], log_eta.shape[1] - 1
    every = all_hypotheses(T, m)
    plain = gibbs_hypotheses(log_eta, 200, np.random.default_rng(seed))
    more = gibbs_hypotheses(log_eta, 200, np.random.default_rng(seed), misses=True)
    held = {tuple(h) for h in more}
    assert {tuple(g) for g in plain} <= held <= {tuple(g) for g in every}
    best = best_hypothesis(log_eta)
    for i in range(T):
        g = best.copy()
        g[i] = 0
        assert tuple(g) in held
    # each with its exact weight: off the enumeration by at most twice the weight never visited
    p = np.exp(hypothesis_log_weights(log_eta, every))
    p /= p.sum()
    seen = np.array([tuple(g) in held for g in every])
    beta = association_marginals(log_eta, "gibbs", np.random.default_rng(seed), samples=200, misses=True)
    assert np.abs(beta - brute_force_marginals(log_eta)).max() <= 2 * p[~seen].sum() + 1e-12


class FixedUniforms:
    """A generator stand-in whose every uniform is ``u``: the sweeps then take a chosen path."""

    def __init__(self, u: float) -> None:
        self.u = u

    def random(self, shape):
        return np.full(shape, self.u)


def test_gibbs_sweeps_start_from_the_best_hypothesis():
    """Two tracks, one measurement: track 0 likely missed, track 1 likely on the measurement, so
    the best hypothesis is (0, 1). Started there, the first sweep finds the measurement held by
    track 1 and must leave track 0 undetected; track 1 then draws from (e^-5, 1) with U = 0.999
    and keeps it. So one sweep visits (0, 1) alone. Started anywhere else (all undetected, say),
    track 0 would draw from (1, e^-5) with U = 0.999 > 1 / (1 + e^-5) and take the measurement."""
    log_eta = np.array([[0.0, -5.0], [-5.0, 0.0]])
    assert 0.999 > 1 / (1 + np.exp(-5.0))
    hyps = gibbs_hypotheses(log_eta, 1, FixedUniforms(0.999))
    assert hyps.tolist() == [[0, 1]]


def test_marginals_survive_a_spread_of_log_weights_beyond_the_exponents_range():
    """One track, one measurement, eta = (1, e^-1000): beta = (1, e^-1000) / (1 + e^-1000), i.e.
    (1, 0) in floating point. The weights must be scaled by the largest (exp(1000) overflows)."""
    log_eta = np.array([[0.0, -1000.0]])
    beta = marginals(log_eta, np.array([[0], [1]]))
    np.testing.assert_array_equal(beta, [[1.0, 0.0]])
    # the other way round column 0 is floored at LOG_FLOOR = -700: beta = (e^-700, 1) / (1 + e^-700)
    beta = marginals(np.array([[-1000.0, 0.0]]), np.array([[0], [1]]))
    np.testing.assert_allclose(beta, [[np.exp(LOG_FLOOR), 1.0]], rtol=1e-12, atol=0)
