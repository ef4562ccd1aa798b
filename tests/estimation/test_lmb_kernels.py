"""The LMB filter's compiled kernels against their plain-numpy twins: the association factors
(and, from them, the Bernoulli filter's bracket L_i), the per-track means <f_c> and the
posterior particle weights."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp

from trackjam.estimation.kernels import kernel_update_factors
from trackjam.estimation.lmb_kernels import (
    kernel_association_factors,
    kernel_ball,
    kernel_beyond_cone,
    kernel_log_means,
    kernel_mixture_log_weights,
    kernel_seen_factors,
)
from trackjam.radio.antenna import cone_gain
from trackjam.radio.measurement import h, wrap_angle

from test_lmb import ANT, AX, LOG_KAPPA, SIGMA, U, factors_twin, scan


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 4), st.sampled_from([0.0, 0.3, 1.0]))
def test_association_factors_equal_numpy_twin_and_the_bernoulli_kernel(seed, m, level):
    rng = np.random.default_rng(seed)
    X = np.hstack([U + rng.normal(0, 4, (200, 3)) + 4 * AX, rng.normal(0, 1, (200, 3))])
    Z = np.array([h(X[rng.integers(200)], U) + rng.normal(0, 1, 3) * SIGMA for _ in range(m)]).reshape(-1, 3)
    Z[:, 1] = wrap_angle(Z[:, 1])
    level_w = level * ANT.l_max
    sc = scan(Z, level_w)
    p_d, log_g = kernel_association_factors(X, sc.Z, U, sc.axis, sc.p_d_scale, ANT.height, ANT.tan_half, ANT.r0,
                                            ANT.n_e, SIGMA, LOG_KAPPA)
    p_twin, g_twin = factors_twin(X, sc.Z, level_w)
    np.testing.assert_allclose(p_d, p_twin, atol=1e-12)
    np.testing.assert_array_equal(np.isfinite(log_g), np.isfinite(g_twin))
    np.testing.assert_allclose(log_g[np.isfinite(log_g)], g_twin[np.isfinite(g_twin)], atol=1e-9)
    # the Bernoulli filter's bracket L_i = 1 - p_D + p_D sum_j g_j / kappa, from these factors
    _, log_L = kernel_update_factors(X, sc.Z, U, sc.axis, sc.p_d_scale, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e,
                                     SIGMA, LOG_KAPPA)
    L = 1 - p_d + p_d * np.exp(log_g).sum(axis=1)
    np.testing.assert_allclose(np.log(L), log_L, rtol=1e-9, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 50), st.integers(0, 4), st.floats(0.0, 0.6))
def test_log_mean_and_mixture_kernels_equal_numpy_twins(seed, n, m, share_inf):
    """The compiled <f_c> and posterior weights against scipy's logsumexp over the factor matrix
    [log(1 - p_D), log p_D + log g_j] of every particle (0 and -inf off the seen ones), -inf
    entries included (a measurement beyond the gate, a column with beta = 0, p_D = 1)."""
    rng = np.random.default_rng(seed)
    log_w = rng.normal(0, 2, n)
    log_w -= logsumexp(log_w)
    seen = np.flatnonzero(rng.random(n) >= share_inf)
    k = len(seen)
    log_p_d = rng.normal(-1, 1, k)
    log_miss = np.where(rng.random(k) < share_inf / 4, -np.inf, rng.normal(-0.5, 0.5, k))
    log_g = np.where(rng.random((k, m)) < share_inf, -np.inf, rng.normal(0, 5, (k, m)))
    log_f = np.column_stack([np.zeros(n), np.full((n, m), -np.inf)])
    log_f[seen] = np.column_stack([log_miss, log_p_d[:, None] + log_g])
    coef = np.where(rng.random(m + 1) < share_inf, -np.inf, rng.normal(0, 3, m + 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        np.testing.assert_allclose(kernel_log_means(log_w, seen, log_miss, log_p_d, log_g),
                                   logsumexp(log_w[:, None] + log_f, axis=0), rtol=1e-12, atol=1e-12)
        use = np.isfinite(coef)
        if not use.any() or not np.isfinite(log_f[:, use]).any():
            return
        twin = log_w + logsumexp(log_f[:, use] + coef[use], axis=1)
        twin -= logsumexp(twin)
    np.testing.assert_allclose(kernel_mixture_log_weights(log_w, seen, log_miss, log_p_d, log_g, coef), twin,
                               rtol=1e-12, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 4))
def test_seen_factors_are_the_full_factors_at_the_particles_in_the_cone(seed, m):
    """The compressed factors are the full ones (p_D > 0) at exactly the particles they list."""
    rng = np.random.default_rng(seed)
    X = np.hstack([U + rng.normal(0, 4, (300, 3)) + 4 * AX, rng.normal(0, 1, (300, 3))])
    Z = np.array([h(X[rng.integers(300)], U) + rng.normal(0, 1, 3) * SIGMA for _ in range(m)]).reshape(-1, 3)
    sc = scan(Z)
    args = (X, sc.Z, U, sc.axis, sc.p_d_scale, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e, SIGMA, LOG_KAPPA)
    seen, p_seen, g_seen = kernel_seen_factors(*args)
    p_d, log_g = factors_twin(X, sc.Z, ANT.l_max)
    np.testing.assert_array_equal(seen, np.flatnonzero(p_d > 0))
    np.testing.assert_allclose(p_seen, p_d[seen], atol=1e-12)
    np.testing.assert_array_equal(np.isfinite(g_seen), np.isfinite(log_g[seen]))
    np.testing.assert_allclose(g_seen[np.isfinite(g_seen)], log_g[seen][np.isfinite(log_g[seen])], atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 300), st.floats(0.05, 30.0), st.floats(0.0, 60.0))
def test_a_ball_beyond_the_cone_holds_no_particle_in_it(seed, n, spread, distance):
    """The ball holds every particle (its centre the mean); whenever the ball test says it lies
    beyond the cone, every particle's cone gain (numpy's Eq. 9 geometry) and the compiled p_D
    are 0; a small cloud far behind the apex is always beyond, one on the axis never."""
    rng = np.random.default_rng(seed)
    direction = rng.normal(size=3)
    centre = U + distance * direction / np.linalg.norm(direction)
    X = np.hstack([centre + rng.normal(0, spread, (n, 3)), np.zeros((n, 3))])
    c, radius = kernel_ball(X)
    np.testing.assert_allclose(c, X[:, :3].mean(axis=0), rtol=1e-12, atol=1e-12)
    assert radius == pytest.approx(np.linalg.norm(X[:, :3] - c, axis=1).max(), rel=1e-12)
    if kernel_beyond_cone(c, radius, U, AX, ANT.height, ANT.tan_half, 1e-6):
        assert not np.any(cone_gain(X[:, :3], U, U + AX, ANT) > 0)
        sc = scan(np.zeros((0, 3)))
        p_d, _ = kernel_association_factors(X, sc.Z, U, sc.axis, sc.p_d_scale, ANT.height, ANT.tan_half, ANT.r0,
                                            ANT.n_e, SIGMA, LOG_KAPPA)
        assert not np.any(p_d > 0)
    for cloud, beyond in ((U - 30 * AX, True), (U + 10 * AX, False)):
        X = np.hstack([cloud + rng.normal(0, 0.5, (n, 3)), np.zeros((n, 3))])
        assert kernel_beyond_cone(*kernel_ball(X), U, AX, ANT.height, ANT.tan_half, 1e-6) == beyond
