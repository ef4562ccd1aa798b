"""The compiled kernels of the Bernoulli filter agree with plain numpy on small cases."""

import math

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from trackjam.config import load_scenario
from trackjam.estimation.kernels import (
    GATE,
    kernel_cv_predict,
    kernel_gated_log_g,
    kernel_gaussian_sample,
    kernel_log_gaussian_mixture,
    kernel_logsumexp,
    kernel_masked_moments,
    kernel_position_proposal,
    kernel_reachable,
    kernel_split_sums,
    kernel_systematic_indices,
    kernel_take_rows,
    kernel_two_scan_velocity,
    kernel_update_factors,
    kernel_weighted_moments,
    kernel_young_weights,
)
from trackjam.radio.antenna import axis_of, detection_probability
from trackjam.radio.measurement import clutter_density, h, wrap_angle
from trackjam.world.motion import cv_matrices
from trackjam.simulation.build import antenna_model

S = load_scenario("paper-fig3")
ANT = antenna_model(S)
SIGMA = np.asarray(S.sensor.noise_std)
LOG_LC = math.log(S.sensor.clutter_rate * clutter_density(ANT.max_range))


def reference_update_factors(X, Z, u, aim, level_w):
    """L_i = (1 - p_D) + p_D sum_y g(y | x_i) / (lambda_c p_c), straight from the definitions."""
    p_d = detection_probability(X[:, :3], u, aim, level_w, ANT)
    ratio = np.zeros(len(X))
    for y in Z:
        r = y - h(X, u)
        r[:, 1:] = wrap_angle(r[:, 1:])
        g = np.exp(-0.5 * np.sum((r / SIGMA) ** 2, axis=1)) / ((2 * np.pi) ** 1.5 * np.prod(SIGMA))
        ratio += g / math.exp(LOG_LC)
    return p_d, (1 - p_d) + p_d * ratio


def _case(rng, n=40, m=5):
    u = np.array([10.0, 20.0, 30.0])
    aim = np.array([14.0, 23.0, 33.0])
    X = np.hstack([aim + rng.normal(0, 3, (n, 3)), rng.normal(0, 1, (n, 3))])
    Z = h(aim + rng.normal(0, 1, (m, 3)), u)
    Z[-1] = [3.0, 3.1, 0.2]  # azimuth next to the wrap at pi
    return X, Z, u, aim


@pytest.mark.parametrize("level_w", [0.0, 1e-5, 0.1995, ANT.l_max])
@pytest.mark.parametrize("m", [0, 1, 5])
def test_update_factors_match_numpy(level_w, m):
    rng = np.random.default_rng(3)
    X, Z, u, aim = _case(rng, m=max(m, 1))
    Z = Z[:m]
    p_d, log_L = kernel_update_factors(
        X, Z, u, axis_of(u, aim), level_w / ANT.l_max * ANT.p_d_max, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e,
        SIGMA, LOG_LC,
    )
    p_ref, L_ref = reference_update_factors(X, Z, u, aim, level_w)
    np.testing.assert_allclose(p_d, p_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.exp(log_L), L_ref, rtol=1e-10)


def reference_log_update_factors(X, Z, u, aim, level_w, log_lc):
    """log L_i in the log domain, for clutter rates so small that g / (lambda_c p_c) overflows:
    logaddexp(log(1 - p_D), log p_D + logsumexp_y log g(y | x_i) - log(lambda_c p_c)), the
    measurements GATE standard deviations or more away left out as the kernel leaves them out
    (with lambda_c p_c ~ e^-800 even a gated-out term would outweigh a miss)."""
    p_d = detection_probability(X[:, :3], u, aim, level_w, ANT)
    log_g = np.full((len(Z), len(X)), -np.inf)
    for j, y in enumerate(Z):
        r = y - h(X, u)
        r[:, 1:] = wrap_angle(r[:, 1:])
        d2 = np.sum((r / SIGMA) ** 2, axis=1)
        log_g[j] = np.where(d2 < GATE**2, -0.5 * d2 - 1.5 * math.log(2 * np.pi) - np.log(SIGMA).sum(), -np.inf)
    with np.errstate(divide="ignore"):
        log_detect = np.log(p_d) + np.logaddexp.reduce(log_g, axis=0) - log_lc
        return p_d, np.logaddexp(np.log1p(-p_d), log_detect)


@pytest.mark.parametrize("level_w", [1e-5, 0.1995, ANT.l_max])
def test_update_factors_of_a_tiny_clutter_rate_match_the_log_domain_formula(level_w):
    """log(lambda_c p_c) = -800 puts the kernel on its log-domain branch (c_max >= 700, where
    exp(c_max) overflows), which the clutter rates above never reach. Guards that branch's
    log p_D + c_max + log S: dropping log p_D (the mutation audit's M-E1) went unnoticed."""
    rng = np.random.default_rng(3)
    X, Z, u, aim = _case(rng, m=5)
    log_lc = -800.0
    assert -1.5 * math.log(2 * np.pi) - np.log(SIGMA).sum() - log_lc >= 700.0  # the log-domain branch
    p_d, log_L = kernel_update_factors(
        X, Z, u, axis_of(u, aim), level_w / ANT.l_max * ANT.p_d_max, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e,
        SIGMA, log_lc,
    )
    p_ref, log_L_ref = reference_log_update_factors(X, Z, u, aim, level_w, log_lc)
    np.testing.assert_allclose(p_d, p_ref, rtol=1e-12, atol=1e-15)
    # the case holds particles that detect (0 < p_D < 1) with a measurement inside the gate, and
    # particles whose L is the miss term alone
    supported = np.isfinite(log_L_ref) & (log_L_ref > 1.0)
    assert supported.sum() >= 5 and np.all((p_ref[supported] > 0) & (p_ref[supported] < 1))
    assert np.any(~supported)
    np.testing.assert_allclose(log_L, log_L_ref, rtol=1e-12, atol=1e-9)


def test_azimuth_residual_is_wrapped():
    """A measurement at azimuth -pi + 0.01 and a particle at pi - 0.01 are 0.02 rad apart."""
    u = np.zeros(3)
    x = np.array([[-5.0 * math.cos(0.01), 5.0 * math.sin(0.01), 0.0, 0, 0, 0]])
    z = h(x, u)
    z[0, 1] = -math.pi + 0.01
    _, log_L = kernel_update_factors(x, z, u, np.array([-1.0, 0, 0]), 0.95, 40.0, ANT.tan_half, 6.0, 2.0, SIGMA, LOG_LC)
    p_ref, L_ref = reference_update_factors(x, z, u, np.array([-1.0, 0, 0]), ANT.l_max)
    assert L_ref[0] > 100  # the residual is small, the measurement strongly supports x
    np.testing.assert_allclose(np.exp(log_L), L_ref, rtol=1e-10)


def test_gated_log_g_is_the_mahalanobis_term_inside_the_gate():
    """c - d2 / 2 from the wrapped residuals, -inf GATE standard deviations or more away; the
    measurements straddle the gate in range alone, in azimuth alone and in all three."""
    rng = np.random.default_rng(9)
    X, _, u, aim = _case(rng)
    sd = np.array([0.5, 0.05, 0.05])
    for i in range(len(X)):
        z = h(X[i : i + 1], u)[0]
        Z = z + rng.normal(0, 1, (12, 3)) * sd * rng.choice([0.5, 5.0, 9.0, 14.0], (12, 1))
        Z[:, 1:] = wrap_angle(Z[:, 1:])
        out = np.full((2, len(Z)), np.nan)
        kernel_gated_log_g(X, i, u, Z, sd[0], sd[1], sd[2], -1.5, out, 1)
        r = Z - z
        r[:, 1:] = wrap_angle(r[:, 1:])
        d2 = np.sum((r / sd) ** 2, axis=1)
        expected = np.where(d2 < GATE**2, -1.5 - 0.5 * d2, -np.inf)
        np.testing.assert_allclose(out[1], expected, rtol=1e-9, atol=1e-9)
        assert np.all(np.isnan(out[0]))  # only row k is written
        assert np.isinf(out[1]).any() and np.isfinite(out[1]).any()


def test_reachable_is_every_axis_within_the_velocity_box():
    rng = np.random.default_rng(10)
    P, mu = rng.uniform(0, 10, (50, 3)), rng.uniform(0, 10, (6, 3))
    sd, dt, v_b = rng.uniform(0.1, 1.0, (6, 3)), 2.0, 1.5
    ref = np.all(np.abs(mu[None] - P[:, None]) / dt <= v_b + 3.0 * sd[None], axis=2)
    got = np.array([[kernel_reachable(mu, j, P, i, dt, v_b, sd) for j in range(6)] for i in range(50)])
    assert np.array_equal(got, ref) and ref.any() and not ref.all()


def test_systematic_indices_match_numpy():
    rng = np.random.default_rng(0)
    w = rng.random(50)
    w /= w.sum()
    u0 = 0.37
    ref = np.searchsorted(np.cumsum(w), (np.arange(200) + u0) / 200)
    np.testing.assert_array_equal(kernel_systematic_indices(w, 200, u0), np.minimum(ref, 49))


def test_systematic_indices_of_degenerate_weights_match_numpy():
    """One particle, all-zero weights and weights summing to less than 1: the compiled draws
    are numpy's searchsorted of the cumulative sum clipped to the last index (the kernel's
    docstring), and never an index past the array."""
    for w in (np.ones(1), np.zeros(1), np.zeros(5), np.full(5, 0.1), np.r_[0.0, 0.0, 1.0]):
        for n_out, u0 in ((1, 0.0), (7, 0.37), (20, 0.999)):
            ref = np.minimum(np.searchsorted(np.cumsum(w), (np.arange(n_out) + u0) / n_out), len(w) - 1)
            np.testing.assert_array_equal(kernel_systematic_indices(w, n_out, u0), ref)


def test_no_configuration_gives_the_resampler_an_empty_set():
    """kernel_systematic_indices reads w[0] unchecked: its callers rely on every filter holding
    at least one particle, which the configuration's bounds guarantee."""
    from trackjam.errors import ConfigError

    for field, least in (("filter.particles", 10), ("filter.birth_particles", 1)):
        with pytest.raises(ConfigError, match=field):
            load_scenario("paper-fig3", [f"{field}={least - 1}"])
        assert getattr(load_scenario("paper-fig3", [f"{field}={least}"]).filter, field.split(".")[1]) == least


def test_systematic_resampling_keeps_expected_counts():
    """Each particle is copied floor(n w_i) or ceil(n w_i) times."""
    rng = np.random.default_rng(1)
    w = rng.random(30)
    w /= w.sum()
    counts = np.bincount(kernel_systematic_indices(w, 1000, rng.uniform()), minlength=30)
    assert np.all(np.abs(counts - 1000 * w) < 1.0 + 1e-9)


def test_weighted_moments_and_logsumexp_match_numpy():
    rng = np.random.default_rng(2)
    X = rng.normal(50, 10, (300, 6))
    w = rng.random(300)
    w /= w.sum()
    mean, cov = kernel_weighted_moments(X, w)
    np.testing.assert_allclose(mean, w @ X, rtol=1e-12)
    np.testing.assert_allclose(cov, np.cov(X.T, aweights=w, bias=True), rtol=1e-10, atol=1e-10)
    a = rng.normal(0, 300, 100)
    assert kernel_logsumexp(a) == pytest.approx(np.logaddexp.reduce(a), rel=1e-12)
    assert kernel_logsumexp(np.full(3, -np.inf)) == -np.inf


def reference_moments_in_order(X, w, inside=None, mass=None):
    """Weighted mean and covariance summed particle by particle in plain numpy, in the order
    the kernels promise (mean: w_i x_i added in turn, then / mass when masked; covariance: per
    particle the outer product of ``w_i (x_i - mean)`` and ``x_i - mean`` added in turn)."""
    rows = range(len(X)) if inside is None else np.flatnonzero(inside)
    mean = np.zeros(6)
    for i in rows:
        mean += w[i] * X[i]
    if inside is not None:
        mean /= mass
    acc = np.zeros((6, 6))
    for i in rows:
        wi = w[i] if inside is None else w[i] / mass
        diff = X[i] - mean
        acc += np.outer(wi * diff, diff)
    return mean, 0.5 * (acc + acc.T)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e6])
def test_moments_kernels_match_the_in_order_sums_to_the_bit(scale):
    """kernel_weighted_moments and kernel_masked_moments keep their sums in registers, a few
    rows of the covariance per pass: each entry must still be the same sum in the same order."""
    rng = np.random.default_rng(7)
    X = rng.normal(0, scale, (257, 6)) + rng.normal(0, 50, 6)
    w = rng.random(257) ** 5
    w[rng.random(257) < 0.2] = 0.0
    w /= w.sum()
    for got, ref in zip(kernel_weighted_moments(X, w), reference_moments_in_order(X, w)):
        assert np.array_equal(got, ref)
    inside = rng.random(257) < 0.4
    mass = w[inside].sum()
    for got, ref in zip(kernel_masked_moments(X, w, inside, mass), reference_moments_in_order(X, w, inside, mass)):
        assert np.array_equal(got, ref)
    empty = kernel_weighted_moments(np.empty((0, 6)), np.empty(0))
    assert np.array_equal(empty[0], np.zeros(6)) and np.array_equal(empty[1], np.zeros((6, 6)))


def test_gaussian_mixture_matches_scipy():
    rng = np.random.default_rng(4)
    mu = rng.normal(0, 2, (3, 3))
    A = rng.normal(0, 1, (3, 3, 3))
    covs = A @ A.transpose(0, 2, 1) + np.eye(3)
    L = np.linalg.cholesky(covs)
    P = rng.normal(0, 3, (20, 3))
    got = kernel_log_gaussian_mixture(P, mu, np.linalg.inv(L), np.log(np.diagonal(L, axis1=1, axis2=2)).sum(1))
    ref = np.log(np.mean([multivariate_normal(mu[k], covs[k]).pdf(P) for k in range(3)], axis=0))
    np.testing.assert_allclose(got, ref, rtol=1e-10)


def _fma_order_reference(mu, L, comp, xi):
    """mu_c + fma(L_c2, xi_2, fma(L_c0, xi_0, L_c1 xi_1)) per row, every step rounded once, in
    exact rational arithmetic: the order kernel_gaussian_sample promises on every machine."""
    from fractions import Fraction as F

    def fma(a, b, c):
        return float(F(a) * F(b) + F(c))

    out = np.empty((len(comp), 3))
    for i, c in enumerate(comp):
        for a in range(3):
            t = float(L[c, a, 1] * xi[i, 1])
            t = fma(L[c, a, 0], xi[i, 0], t)
            t = fma(L[c, a, 2], xi[i, 2], t)
            out[i, a] = mu[c, a] + t
    return out


def test_gaussian_sample_sums_in_its_fixed_order_bit_for_bit():
    """The compiled draw equals the rational-arithmetic reference of its summation order exactly
    (a reordered sum, or products not fused, fail here on any machine); and where numpy's
    stacked matmul sums in that order (OpenBLAS's x86-64 kernels with FMA), it equals numpy's
    draw exactly, which is what keeps the runs of earlier versions."""
    rng = np.random.default_rng(12)
    mu = rng.normal(0, 30, (4, 3))
    A = rng.normal(0, 2, (4, 3, 3))
    L = np.linalg.cholesky(A @ A.transpose(0, 2, 1) + 0.25 * np.eye(3))
    comp = rng.integers(4, size=400)
    xi = rng.standard_normal((400, 3))
    got = kernel_gaussian_sample(mu, L, comp, xi)
    np.testing.assert_array_equal(got, _fma_order_reference(mu, L, comp, xi))
    numpy_draw = mu[comp] + (L[comp] @ xi[:, :, None])[:, :, 0]
    if not np.array_equal(numpy_draw, _fma_order_reference(mu, L, comp, xi)):
        pytest.skip("this numpy's matmul sums in another order (no FMA kernel): the exact check against it does not apply")
    np.testing.assert_array_equal(got, numpy_draw)


def test_gaussian_sample_is_the_mixture_draw_of_numpy():
    """The compiled draw is mu_c + L_c xi, as numpy computes it: within a few units in the last
    place on any machine, and exactly where no rounding can differ."""
    rng = np.random.default_rng(7)
    for k, n in ((1, 1), (1, 500), (4, 2000), (5, 3)):
        mu = rng.normal(0, 30, (k, 3))
        A = rng.normal(0, 2, (k, 3, 3))
        L = np.linalg.cholesky(A @ A.transpose(0, 2, 1) + 0.25 * np.eye(3))
        comp = rng.integers(k, size=n)
        xi = rng.standard_normal((n, 3))
        got = kernel_gaussian_sample(mu, L, comp, xi)
        ref = mu[comp] + (L[comp] @ xi[:, :, None])[:, :, 0]
        np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-12)
    # integers: every product and sum is exact, so any order gives the same bits
    L = np.tril(rng.integers(-9, 10, (2, 3, 3))).astype(float)
    mu = rng.integers(-99, 100, (2, 3)).astype(float)
    comp = rng.integers(2, size=50)
    xi = rng.integers(-9, 10, (50, 3)).astype(float)
    np.testing.assert_array_equal(kernel_gaussian_sample(mu, L, comp, xi), mu[comp] + np.einsum("nab,nb->na", L[comp], xi))


def test_cv_predict_is_eq1():
    rng = np.random.default_rng(5)
    X = rng.normal(0, 5, (10, 6))
    xi = rng.normal(0, 1, (10, 3))
    Phi, Gamma = cv_matrices(1.0)
    ref = X @ Phi.T + (0.7 * xi) @ Gamma.T
    kernel_cv_predict(X, xi, 1.0, 0.7)
    np.testing.assert_allclose(X, ref, rtol=1e-12)


def reference_two_scan_velocity(P, V, mu, cov, v_b, blind, u_aim, u_pick, xi):
    """The two-scan velocity proposal in plain numpy: reachable measurements, the aimed draw,
    and log q_v = log(blind U(v) + (1 - blind) (1 / r) sum_reachable N(v; (mu_j - p), C_j))."""
    chol = np.linalg.cholesky(cov)
    sd = np.sqrt(np.diagonal(cov, axis1=1, axis2=2))
    mean_v = mu[None, :, :] - P[:, None, :]
    reach = np.all(np.abs(mean_v) <= v_b + 3.0 * sd[None], axis=2)
    r = reach.sum(axis=1)
    V = V.copy()
    for i in np.flatnonzero((u_aim >= blind) & (r > 0)):
        j = np.flatnonzero(reach[i])[int(np.floor(u_pick[i] * r[i]))]
        V[i] = mean_v[i, j] + chol[j] @ xi[i]
    dens_u = np.where(np.all(np.abs(V) <= v_b, axis=1), (2 * v_b) ** -3.0, 0.0)
    dens_a = np.zeros(len(P))
    for j in range(len(mu)):
        dens_a += reach[:, j] * multivariate_normal(np.zeros(3), cov[j]).pdf(V - mean_v[:, j])
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(r > 0, blind * dens_u + (1 - blind) * dens_a / np.maximum(r, 1), dens_u)
        return V, np.log(q)


def test_two_scan_velocity_matches_numpy():
    rng = np.random.default_rng(6)
    k, m, v_b = 400, 4, 3.0
    P = rng.uniform(0, 10, (k, 3))
    mu = rng.uniform(0, 10, (m, 3))
    A = rng.normal(0, 0.6, (m, 3, 3))
    cov = A @ A.transpose(0, 2, 1) + 0.3 * np.eye(3)
    V0 = rng.uniform(-v_b, v_b, (k, 3))
    u_aim, u_pick, xi = rng.random(k), rng.random(k), rng.standard_normal((k, 3))
    chol = np.linalg.cholesky(cov)
    V = V0.copy()
    got = kernel_two_scan_velocity(
        P, V, mu, chol, np.linalg.inv(chol), np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(1),
        np.sqrt(np.diagonal(cov, axis1=1, axis2=2)), v_b, 1.0, 0.25, u_aim, u_pick, xi,
    )
    V_ref, ref = reference_two_scan_velocity(P, V0, mu, cov, v_b, 0.25, u_aim, u_pick, xi)
    np.testing.assert_allclose(V, V_ref, rtol=1e-12)
    assert np.any(np.abs(V) > v_b) and np.any(V != V0)  # aimed draws, some beyond b's velocity box
    np.testing.assert_allclose(got, ref, rtol=1e-10)


# -- kernels that replace numpy steps of the filter: each must give numpy's values bit for bit --

def reference_log_mixture_in_order(P, mu, Linv, log_det):
    """kernel_log_gaussian_mixture's online log-sum-exp in plain Python, every exp called (the
    kernel skips those whose value is 0): the same floating-point steps in the same order."""
    c = -1.5 * math.log(2.0 * math.pi) - math.log(len(mu))
    out = np.empty(len(P))
    for i, p in enumerate(P):
        mx, acc = -math.inf, 0.0
        for j in range(len(mu)):
            d = [float(p[a] - mu[j, a]) for a in range(3)]
            q = 0.0
            for a in range(3):
                y = 0.0
                for b in range(a + 1):
                    y += float(Linv[j, a, b]) * d[b]
                q += y * y
            t = -float(log_det[j]) - 0.5 * q
            if t > mx:
                acc = acc * math.exp(mx - t) + 1.0
                mx = t
            else:
                acc += math.exp(t - mx)
        out[i] = c + mx + math.log(acc)
    return out


def _far_mixture(rng, n=400):
    """Points and Gaussians a few metres wide spread over 200 m: most terms of the mixture lie
    thousands below its largest (exp of them is 0, which the kernels no longer call for)."""
    mu = rng.uniform(0, 200, (4, 3))
    A = rng.normal(0, 1.5, (4, 3, 3))
    L = np.linalg.cholesky(A @ A.transpose(0, 2, 1) + 0.25 * np.eye(3))
    P = np.vstack([rng.uniform(0, 200, (n - 40, 3)), mu[rng.integers(4, size=40)] + rng.normal(0, 2, (40, 3))])
    return P, mu, L


def test_gaussian_mixture_skipping_vanishing_terms_is_the_same_to_the_bit():
    rng = np.random.default_rng(21)
    P, mu, L = _far_mixture(rng)
    Linv, log_det = np.linalg.inv(L), np.log(np.diagonal(L, axis1=1, axis2=2)).sum(1)
    ref = reference_log_mixture_in_order(P, mu, Linv, log_det)
    got = kernel_log_gaussian_mixture(P, mu, Linv, log_det)
    assert np.array_equal(got, ref)
    assert math.exp(-750.0) == 0.0 and math.exp(-745.2) == 0.0  # the threshold lies where exp is 0


def reference_position_proposal(R, b_low, b_high, v, n_u, mu, L, comp, xi):
    """``_position_proposal`` as numpy composed it before its kernel: b's draw, the mixture's
    draws into rows n_u:, its density (kernel_log_gaussian_mixture, held to numpy above) plus the
    area's log volume, np.logaddexp of the two shares, +inf outside the area."""
    k = len(R)
    lo = np.concatenate([b_low, np.full(3, -v)])
    span = np.concatenate([b_high - b_low, np.full(3, 2.0 * v)])
    X = lo + R * span
    X[n_u:, :3] = kernel_gaussian_sample(mu, L, comp, xi)
    log_volume = float(np.sum(np.log(b_high - b_low)))
    log_G = kernel_log_gaussian_mixture(np.ascontiguousarray(X[:, :3]), mu, np.linalg.inv(L),
                                        np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)) + log_volume
    n_p = k - n_u
    log_q = np.logaddexp(math.log(n_u / k) if n_u else -np.inf, math.log(n_p / k) + log_G)
    log_q[n_u:][~np.all((X[n_u:, :3] >= b_low) & (X[n_u:, :3] <= b_high), axis=1)] = np.inf
    return X, log_q


@pytest.mark.parametrize("n_u", [0, 1, 150, 399])
def test_position_proposal_is_the_numpy_composition_to_the_bit(n_u):
    rng = np.random.default_rng(22 + n_u)
    k = 400
    P, mu, L = _far_mixture(rng)
    low, high, v = np.zeros(3), np.array([200.0, 180.0, 60.0]), 3.0
    R = rng.random((k, 6))
    comp = rng.integers(4, size=k - n_u)
    xi = rng.standard_normal((k - n_u, 3)) * 3.0  # some draws leave the area
    X_ref, ref = reference_position_proposal(R, low, high, v, n_u, mu, L, comp, xi)
    X = R.copy()
    lo = np.concatenate([low, np.full(3, -v)])
    span = np.concatenate([high - low, np.full(3, 2.0 * v)])
    got = kernel_position_proposal(X, lo, span, n_u, mu, L, comp, xi, np.linalg.inv(L),
                                   np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1),
                                   float(np.sum(np.log(high - low))), math.log(n_u / k) if n_u else -np.inf,
                                   math.log((k - n_u) / k), low, high)
    assert np.array_equal(X, X_ref)
    assert np.array_equal(got, ref)
    if k - n_u > 100:
        assert np.isinf(got[n_u:]).any() and np.isfinite(got).any()


def test_logaddexp_of_the_proposal_is_numpys_to_the_bit():
    """The proposal kernel's logaddexp is numpy's, infinities, ties and NaN included: rows whose
    mixture density is given by hand through a one-Gaussian mixture of known log-density."""
    rng = np.random.default_rng(23)
    k = 3000
    mu, L = np.zeros((1, 3)), np.eye(3)[None] * 1e-3
    R = np.zeros((k, 6))  # every row at the low corner (0, 0, 0): the mixture's mean
    # log G = -1.5 log(2 pi) - log det L; pick shares so that the two arguments of logaddexp run
    # over a wide range, their tie included
    base = -1.5 * math.log(2 * math.pi) - 3 * math.log(1e-3)
    for share_p in list(rng.normal(0, 400, 200)) + [-base, -base + 1e-12, np.inf, -np.inf, np.nan]:
        for share_u in (math.log(0.25), -np.inf, 0.0, 700.0):
            got = kernel_position_proposal(R.copy(), np.zeros(6), np.ones(6), k, mu, L, np.zeros(0, dtype=np.int64),
                                           np.zeros((0, 3)), np.linalg.inv(L), np.log(np.diagonal(L, axis1=1, axis2=2)).sum(1),
                                           0.0, share_u, share_p, np.zeros(3), np.ones(3))[:1]
            log_G = kernel_log_gaussian_mixture(np.zeros((1, 3)), mu, np.linalg.inv(L),
                                                np.log(np.diagonal(L, axis1=1, axis2=2)).sum(1)) + 0.0
            with np.errstate(invalid="ignore"):
                ref = np.logaddexp(share_u, share_p + log_G)
            assert np.array_equal(got, ref, equal_nan=True), (share_u, share_p)


def test_young_weights_are_the_numpy_expression_to_the_bit():
    rng = np.random.default_rng(24)
    k, v_b = 500, 3.0
    V = rng.uniform(-3.3, 3.3, (k, 3))
    V[0] = [3.0, -3.0, 0.0]  # on the box's faces: inside
    V[1, 2] = np.nan
    log_L, log_qp, log_qv = rng.normal(0, 5, k), rng.normal(0, 5, k), rng.normal(0, 5, k)
    log_qp[rng.random(k) < 0.1] = np.inf
    log_qp[2], log_qv[3], log_L[4], log_qv[5] = np.nan, -np.inf, -np.inf, np.nan
    log_U = -3.0 * math.log(2.0 * v_b)
    in_box = np.all(np.abs(V) <= v_b, axis=1)
    with np.errstate(invalid="ignore"):
        ref = np.where(in_box & np.isfinite(log_qp), log_U + log_L - log_qp - log_qv, -np.inf)
    got = kernel_young_weights(V, v_b, log_U, log_L, log_qp, log_qv)
    assert np.array_equal(got, ref, equal_nan=True)
    assert in_box[0] and not in_box.all()


def test_take_rows_is_fancy_indexing():
    rng = np.random.default_rng(25)
    X = rng.normal(size=(300, 6))
    for idx in (np.sort(rng.integers(0, 300, 500)), rng.integers(0, 300, 7), np.zeros(0, dtype=np.int64)):
        got = kernel_take_rows(X, idx)
        assert got.shape == (len(idx), 6) and np.array_equal(got, X[idx])
    X[0, 0] = X[0, 0] + 1.0  # a copy, not a view
    assert got.base is None or got.base is not X


def test_split_sums_are_the_in_order_sums_of_each_part():
    rng = np.random.default_rng(26)
    w = rng.random(1000) ** 3
    mask = rng.random(1000) < 0.3
    s_in, s_out = kernel_split_sums(w, mask)
    ref_in = ref_out = 0.0
    for x, m in zip(w, mask):
        if m:
            ref_in += x
        else:
            ref_out += x
    assert (s_in, s_out) == (ref_in, ref_out)
    assert s_in == pytest.approx(w[mask].sum(), rel=1e-13) and kernel_split_sums(w, np.zeros(1000, bool))[0] == 0.0
