"""Compiled hot loops of the Bernoulli particle filter (Section V-A).

:func:`kernel_update_factors` is the per-particle part of the update: for particle ``x_i`` it
returns ``p_D(x_i)`` (Eq. 9) and the log of the update factor

    L_i = (1 - p_D(x_i)) + p_D(x_i) * sum_{y in Y_t} g_t(y | x_i, u_t) / (lambda_c p_c(y)),

so that ``s_t(x_i) ∝ L_i s_{t|t-1}(x_i)`` and ``1 - q_t = sum_i w_i L_i``. Everything is in the
log domain (a clutter-free likelihood ratio g / (lambda_c p_c) easily reaches 1e3).
``tests/estimation/test_kernels.py`` holds it to a plain-numpy twin.
"""

from __future__ import annotations

import math

import llvmlite.ir as llvm_ir  # numba's own dependency, at the version numba pins
import numpy as np
from numba import njit, types
from numba.extending import intrinsic

from trackjam.radio.antenna import kernel_cone_gain

_LOG_2PI = math.log(2.0 * math.pi)
GATE = 11.0  # range gate in standard deviations (exp(-GATE^2 / 2) < 1e-26)


@njit(cache=True)
def _wrap(a):
    """Wrap an angle to [-pi, pi] (the sign at pi is irrelevant inside a Gaussian)."""
    if a > math.pi or a < -math.pi:
        return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))
    return a


@njit(cache=True, inline="always")
def kernel_gated_log_g(X, i, u, Z, s0, s1, s2, c, out, k):
    """Writes into row ``k`` of ``out`` (., m) ``c - d2_j / 2``: d2_j is the squared Mahalanobis
    distance of measurement ``Z[j]`` [rho, az, incl] from particle ``X[i]``'s noise-free
    measurement seen from ``u`` (noise standard deviations s0, s1, s2; angle residuals wrapped),
    so this is log g(y_j | x) up to the constant ``c``; -inf where y_j lies GATE standard
    deviations or more away. The range is gated first, so the angles are computed only when
    some measurement passes it (most particles pass none). A row of a 2-D array, not a 1-D
    view: a view per particle made the LMB kernel 8 % slower."""
    dx = X[i, 0] - u[0]
    dy = X[i, 1] - u[1]
    dz = X[i, 2] - u[2]
    rho_xy = math.sqrt(dx * dx + dy * dy)
    rho = math.sqrt(rho_xy * rho_xy + dz * dz)
    have_angles = False
    az = 0.0
    inc = 0.0
    for j in range(Z.shape[0]):
        out[k, j] = -np.inf
        e0 = (Z[j, 0] - rho) / s0
        if e0 > GATE or e0 < -GATE:
            continue
        if not have_angles:
            az = math.atan2(dy, dx)
            inc = math.atan2(rho_xy, dz)
            have_angles = True
        e1 = _wrap(Z[j, 1] - az) / s1
        e2 = _wrap(Z[j, 2] - inc) / s2
        d2 = e0 * e0 + e1 * e1 + e2 * e2
        if d2 < GATE * GATE:
            out[k, j] = c - 0.5 * d2


@njit(cache=True)
def kernel_update_factors(X, Z, u, axis, p_d_scale, height, tan_half, r0, n_e, noise_std, log_lambda_c):
    """Per particle: ``p_D`` and ``log L_i`` (see the module docstring).

    ``X`` (n, 6) particles, ``Z`` (m, 3) measurements [rho, az, incl], ``u`` (3,) agent
    position, ``axis`` (3,) unit antenna axis, ``p_d_scale = (l / l_max) p_D^max``,
    ``noise_std`` (3,) the diagonal of Sigma_w as standard deviations,
    ``log_lambda_c = log(lambda_c p_c)``.
    """
    n = X.shape[0]
    m = Z.shape[0]
    p_d = np.empty(n)
    log_L = np.empty(n)
    s0, s1, s2 = noise_std[0], noise_std[1], noise_std[2]
    # t_j = log g(y_j | x) - log(lambda_c p_c) = c_max - 0.5 * (Mahalanobis distance)^2
    c_max = -1.5 * _LOG_2PI - math.log(s0) - math.log(s1) - math.log(s2) - log_lambda_c
    linear = c_max < 700.0  # exp(c_max) is finite: L_i can be formed directly
    K = math.exp(c_max) if linear else 0.0
    t = np.empty((1, m))  # t_j - c_max of the particle at hand
    for i in range(n):
        pd = p_d_scale * kernel_cone_gain(
            X[i, 0], X[i, 1], X[i, 2], u[0], u[1], u[2], axis[0], axis[1], axis[2], height, tan_half, r0, n_e
        )
        p_d[i] = pd
        miss = 1.0 - pd
        if pd <= 0.0 or m == 0:
            log_L[i] = math.log(miss) if miss > 0.0 else -np.inf
            continue
        # S = sum_j exp(t_j - c_max); a measurement GATE standard deviations or more away adds
        # less than exp(-GATE^2 / 2) ~ 1e-26 and is skipped
        kernel_gated_log_g(X, i, u, Z, s0, s1, s2, 0.0, t, 0)
        S = 0.0
        for j in range(m):
            if t[0, j] > -np.inf:
                S += math.exp(t[0, j])
        if linear:
            L = miss + pd * K * S
            log_L[i] = math.log(L) if L > 0.0 else -np.inf
        elif S > 0.0:
            log_detect = math.log(pd) + c_max + math.log(S)
            log_miss = math.log(miss) if miss > 0.0 else -np.inf
            hi = max(log_miss, log_detect)
            log_L[i] = hi + math.log1p(math.exp(min(log_miss, log_detect) - hi))
        else:
            log_L[i] = math.log(miss) if miss > 0.0 else -np.inf
    return p_d, log_L


@njit(cache=True)
def kernel_logsumexp(a):
    """log(sum(exp(a))) of a 1-D array; -inf when every entry is -inf."""
    mx = -np.inf
    for v in a:
        if v > mx:
            mx = v
    if mx == -np.inf:
        return -np.inf
    acc = 0.0
    for v in a:
        acc += math.exp(v - mx)
    return mx + math.log(acc)


@njit(cache=True, inline="always")
def _covariance_rows(X, w, inside, mass, mean, a, cov):
    """Rows ``a``, ``a + 1`` and ``a + 2`` of the weighted second central moment of ``X`` (n, 6)
    into ``cov``: ``cov[r, b] = sum_i (w_i / mass) (X[i, r] - mean[r]) (X[i, b] - mean[b])`` over
    the rows where ``inside`` (every row, and weights ``w_i`` undivided, when ``inside`` has length
    0), summed in particle order.

    Each entry gets the same terms in the same order as the one-pass loop it replaces (``acc``
    of 36 entries in memory, per particle ``wa = w_i diff_a`` then ``acc[a, b] += wa diff_b``),
    so the result is the same to the bit; the eighteen sums are held in registers (two passes
    of three rows: 12k particles 128 -> 108 us against three passes of two, which made the
    moments 1.5x faster than the loop in memory)."""
    m0, m1, m2, m3, m4, m5 = mean[0], mean[1], mean[2], mean[3], mean[4], mean[5]
    ma, mb, mc = mean[a], mean[a + 1], mean[a + 2]
    masked = inside.shape[0] > 0
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    t0 = t1 = t2 = t3 = t4 = t5 = 0.0
    v0 = v1 = v2 = v3 = v4 = v5 = 0.0
    for i in range(X.shape[0]):
        if masked and not inside[i]:
            continue
        wi = w[i] / mass if masked else w[i]
        d0, d1, d2 = X[i, 0] - m0, X[i, 1] - m1, X[i, 2] - m2
        d3, d4, d5 = X[i, 3] - m3, X[i, 4] - m4, X[i, 5] - m5
        wa = wi * (X[i, a] - ma)
        wb = wi * (X[i, a + 1] - mb)
        wc = wi * (X[i, a + 2] - mc)
        s0 += wa * d0
        s1 += wa * d1
        s2 += wa * d2
        s3 += wa * d3
        s4 += wa * d4
        s5 += wa * d5
        t0 += wb * d0
        t1 += wb * d1
        t2 += wb * d2
        t3 += wb * d3
        t4 += wb * d4
        t5 += wb * d5
        v0 += wc * d0
        v1 += wc * d1
        v2 += wc * d2
        v3 += wc * d3
        v4 += wc * d4
        v5 += wc * d5
    cov[a, 0], cov[a, 1], cov[a, 2], cov[a, 3], cov[a, 4], cov[a, 5] = s0, s1, s2, s3, s4, s5
    cov[a + 1, 0], cov[a + 1, 1], cov[a + 1, 2], cov[a + 1, 3], cov[a + 1, 4], cov[a + 1, 5] = t0, t1, t2, t3, t4, t5
    cov[a + 2, 0], cov[a + 2, 1], cov[a + 2, 2], cov[a + 2, 3], cov[a + 2, 4], cov[a + 2, 5] = v0, v1, v2, v3, v4, v5


@njit(cache=True)
def _moments(X, w, inside, mass):
    """Mean (6,) and symmetrised covariance (6, 6) of the rows of ``X`` (n, 6) where ``inside``
    with weights ``w / mass``, or of every row with weights ``w`` when ``inside`` has length 0:
    the mean is ``sum_i w_i X_i`` over those rows, then divided by ``mass`` when masked; the
    covariance two passes of :func:`_covariance_rows`."""
    masked = inside.shape[0] > 0
    m0 = m1 = m2 = m3 = m4 = m5 = 0.0
    for i in range(X.shape[0]):
        if masked and not inside[i]:
            continue
        wi = w[i]
        m0 += wi * X[i, 0]
        m1 += wi * X[i, 1]
        m2 += wi * X[i, 2]
        m3 += wi * X[i, 3]
        m4 += wi * X[i, 4]
        m5 += wi * X[i, 5]
    mean = np.array([m0, m1, m2, m3, m4, m5])
    if masked:
        mean /= mass
    cov = np.empty((6, 6))
    for a in range(0, 6, 3):
        _covariance_rows(X, w, inside, mass, mean, a, cov)
    return mean, 0.5 * (cov + cov.T)


@njit(cache=True)
def kernel_weighted_moments(X, w):
    """Mean (6,) and covariance (6, 6) of particles ``X`` (n, 6) with normalised weights ``w``."""
    return _moments(X, w, np.empty(0, dtype=np.bool_), 1.0)


# exp(x) is 0 for every x below about -745.13 (its true value is under half the least subnormal);
# libm reaches that 0 through its slow underflow path (errno, FP flags), which made the mixture
# densities of the birth proposals 2-3 times slower than they need be: below EXP_ZERO the
# helpers below skip the call and use its value, 0, so every result is the same bit for bit
EXP_ZERO = -750.0


@njit(cache=True, inline="always")
def _scaled(acc, x):
    """``acc * exp(x)``, without calling exp where it is 0 (``acc`` finite: ``acc * 0 = 0``)."""
    return acc * math.exp(x) if not x < EXP_ZERO else 0.0 * acc


@njit(cache=True, inline="always")
def _add_exp(acc, x):
    """``acc + exp(x)``, without calling exp where it is 0."""
    return acc + math.exp(x) if not x < EXP_ZERO else acc + 0.0


@njit(cache=True, inline="always")
def _log1p_exp(x):
    """``log1p(exp(x))``, without calling either where exp is 0 (``log1p(0) = 0``)."""
    return math.log1p(math.exp(x)) if not x < EXP_ZERO else 0.0


@njit(cache=True, inline="always")
def _log_mixture_row(P, i, mu, Linv, log_det, c, d):
    """log of (1/k) sum_j N(P[i, :3]; mu_j, Sigma_j) (see :func:`kernel_log_gaussian_mixture`);
    ``c = -1.5 log(2 pi) - log k``, ``d`` a work array of 3."""
    mx = -np.inf
    acc = 0.0
    for j in range(mu.shape[0]):
        for a in range(3):
            d[a] = P[i, a] - mu[j, a]
        q = 0.0
        for a in range(3):
            y = 0.0
            for b in range(a + 1):
                y += Linv[j, a, b] * d[b]
            q += y * y
        t = -log_det[j] - 0.5 * q
        if t > mx:
            acc = _scaled(acc, mx - t) + 1.0
            mx = t
        else:
            acc = _add_exp(acc, t - mx)
    return c + mx + math.log(acc)


@njit(cache=True)
def kernel_log_gaussian_mixture(P, mu, Linv, log_det):
    """log of (1/k) sum_j N(P[i]; mu_j, Sigma_j) at each row of ``P`` (n, 3), given the means
    ``mu`` (k, 3), the inverse Cholesky factors ``Linv`` (k, 3, 3) and ``log_det[j] = log det L_j``."""
    n = P.shape[0]
    out = np.empty(n)
    c = -1.5 * _LOG_2PI - math.log(mu.shape[0])
    d = np.empty(3)
    for i in range(n):
        out[i] = _log_mixture_row(P, i, mu, Linv, log_det, c, d)
    return out


@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM's fused multiply-add)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        f64 = llvm_ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [f64], llvm_ir.FunctionType(f64, [f64, f64, f64]))
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True)
def kernel_gaussian_sample(mu, chol, comp, xi):
    """Draws of a mixture of Gaussians: row i is ``mu[comp[i]] + chol[comp[i]] @ xi[i]`` for
    means ``mu`` (k, 3), Cholesky factors ``chol`` (k, 3, 3) and standard normals ``xi`` (n, 3).

    Each product is summed in one fixed order on every machine: the middle term first, then the
    first and the last fused in (fused multiply-adds). That is how numpy's stacked matmul sums it
    where OpenBLAS runs its x86-64 kernels with fused multiply-adds (Haswell and later, Zen; this
    project's machine), so there the runs of earlier versions, which used that matmul, are
    reproduced bit for bit. Where numpy sums otherwise (x86-64 without FMA, MKL, Accelerate) the
    earlier versions' draws differed from these in the last bit, as they differed from this
    machine's; the draw is the same product either way."""
    n = comp.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        _sample_row(mu, chol, comp[i], xi, i, out, i)
    return out


@njit(cache=True, inline="always")
def _sample_row(mu, chol, c, xi, i, out, r):
    """Row ``r`` of ``out`` (its first 3 columns) = ``mu[c] + chol[c] @ xi[i]``, summed as
    :func:`kernel_gaussian_sample` says."""
    for a in range(3):
        t = chol[c, a, 1] * xi[i, 1]
        t = _fma(chol[c, a, 0], xi[i, 0], t)
        t = _fma(chol[c, a, 2], xi[i, 2], t)
        out[r, a] = mu[c, a] + t


_LOG_2 = math.log(2.0)  # numpy's NPY_LOGE2


@njit(cache=True, inline="always")
def _logaddexp(x, y):
    """``np.logaddexp(x, y)`` as numpy computes it (npymath's ``npy_logaddexp``, libm's exp and
    log1p, which numba calls too): the same value bit for bit, NaN and infinities included."""
    if x == y:
        return x + _LOG_2
    tmp = x - y
    if tmp > 0:
        return x + _log1p_exp(-tmp)
    elif tmp <= 0:
        return y + _log1p_exp(tmp)
    return tmp


@njit(cache=True)
def kernel_position_proposal(X, lo, span, n_u, mu, chol, comp, xi, Linv, log_det, log_volume, log_share_u,
                             log_share_p, low, high):
    """The position part of the birth proposal (estimation/birth.py ``_position_proposal``) after
    its draws, in one pass, in place of the numpy steps it replaces, each value the same bit for
    bit (tests/estimation/test_kernels.py): ``X`` (k, 6) holds uniform numbers in [0, 1) and
    becomes ``lo + X span`` (``UniformBirth.draw``); its rows ``n_u:`` then get the positions
    ``mu[comp] + chol[comp] @ xi`` (:func:`kernel_gaussian_sample`). Returns per row ``log q =
    logaddexp(log_share_u, log_share_p + (log G(p) + log_volume))`` with ``G`` the mixture of
    :func:`kernel_log_gaussian_mixture`, +inf on the rows from ``n_u`` on whose position lies
    outside the box [low, high]."""
    k = X.shape[0]
    for i in range(k):
        for a in range(6):
            X[i, a] = lo[a] + X[i, a] * span[a]
    for i in range(k - n_u):
        _sample_row(mu, chol, comp[i], xi, i, X, n_u + i)
    log_q = np.empty(k)
    c = -1.5 * _LOG_2PI - math.log(mu.shape[0])
    d = np.empty(3)
    for i in range(k):
        log_G = _log_mixture_row(X, i, mu, Linv, log_det, c, d) + log_volume
        lq = _logaddexp(log_share_u, log_share_p + log_G)
        if i >= n_u:
            for a in range(3):
                if not (X[i, a] >= low[a] and X[i, a] <= high[a]):
                    lq = np.inf
        log_q[i] = lq
    return log_q


@njit(cache=True)
def kernel_systematic_indices(w, n_out, u0):
    """Systematic resampling: indices of ``n_out`` draws from normalised weights ``w`` with the
    single uniform offset ``u0`` in [0, 1).

    ``w`` must hold at least one weight: with none it reads ``w[0]`` out of bounds (no check
    here, in the hot path). Its callers never pass none: the Bernoulli filter resamples its
    ``filter.particles`` >= 10 particles (each part of a split resampling only when it holds
    weight), the LMB filter a track's particles, >= ``filter.birth_particles`` >= 1. Weights
    that sum to less than 1 (all zero included) give the last index for every draw past their
    sum, as ``np.searchsorted`` of their cumulative sum clipped to n - 1 does."""
    idx = np.empty(n_out, dtype=np.int64)
    c = w[0]
    k = 0
    n = w.shape[0]
    for i in range(n_out):
        pos = (i + u0) / n_out
        while pos > c and k < n - 1:
            k += 1
            c += w[k]
        idx[i] = k
    return idx


@njit(cache=True)
def kernel_take_rows(X, idx):
    """``X[idx]`` for a 2-D ``X`` and indices ``idx`` within its rows (not checked): a copy, row by
    row (numpy's fancy indexing of 10,000 rows of 6 took 100 us, this 10-15 us)."""
    n = idx.shape[0]
    d = X.shape[1]
    out = np.empty((n, d))
    for i in range(n):
        r = idx[i]
        for a in range(d):
            out[i, a] = X[r, a]
    return out


@njit(cache=True)
def kernel_split_sums(w, mask):
    """In-order sums of ``w`` where ``mask`` and where not: a cheap look at the two masses, not
    numpy's (pairwise) sums; the filter only takes them as a guide where far from a threshold."""
    s_in = 0.0
    s_out = 0.0
    for i in range(w.shape[0]):
        if mask[i]:
            s_in += w[i]
        else:
            s_out += w[i]
    return s_in, s_out


@njit(cache=True)
def kernel_cv_predict(X, xi, dt, sigma_a):
    """Eq. (1) in place: x <- Phi x + Gamma nu with nu = sigma_a * xi, xi (n, 3) standard normal."""
    h = 0.5 * dt * dt
    for i in range(X.shape[0]):
        for a in range(3):
            nu = sigma_a * xi[i, a]
            X[i, a] += dt * X[i, 3 + a] + h * nu
            X[i, 3 + a] += dt * nu


@njit(cache=True)
def kernel_reflect(X, low, high):
    """Fold particles back into the box [low, high] in place, flipping the velocity component
    of each wall crossed: the truth's wall model (world/target.py ``reflect``) for the filter."""
    for i in range(X.shape[0]):
        for a in range(3):
            for _ in range(8):
                if X[i, a] < low[a]:
                    X[i, a] = 2.0 * low[a] - X[i, a]
                    X[i, 3 + a] = -X[i, 3 + a]
                elif X[i, a] > high[a]:
                    X[i, a] = 2.0 * high[a] - X[i, a]
                    X[i, 3 + a] = -X[i, 3 + a]
                else:
                    break
            X[i, a] = min(max(X[i, a], low[a]), high[a])


@njit(cache=True, inline="always")
def kernel_reachable(mu, j, P, i, dt, v_b, sd):
    """Whether measurement j (mean ``mu[j]``) is reachable from position ``P[i]`` in ``dt``: every
    axis of (mu_j - p) / dt within ``v_b + 3 sd[j]``."""
    ok = True
    for a in range(3):
        if abs((mu[j, a] - P[i, a]) / dt) > v_b + 3.0 * sd[j, a]:
            ok = False
    return ok


@njit(cache=True)
def kernel_two_scan_velocity(P, V, mu, chol, Linv, log_det, sd, v_b, dt, blind, u_aim, u_pick, xi):
    """The velocity part of the two-scan proposal (estimation/birth.py ``redraw_young``), in place.

    ``P`` (k, 3) positions at t-1, ``V`` (k, 3) velocities already drawn from U(±v_b) (kept for
    the blind draws, overwritten for the aimed ones); scan t's Gaussians have means ``mu``
    (m, 3) and, as velocity proposals, Cholesky factors ``chol`` (m, 3, 3), their inverses
    ``Linv``, ``log_det[j] = log det chol_j`` and per-axis standard deviations ``sd`` (m, 3).
    Measurement j is reachable from p when every axis of (mu_j - p) / dt lies within
    ``v_b + 3 sd_j``. With ``u_aim[i] >= blind`` and some measurement reachable, particle i takes
    the ``floor(u_pick[i] r_i)``-th reachable one and ``v = (mu_j - p) / dt + chol_j xi[i]``.
    Returns ``log q_v(v | p)`` of the whole mixture per particle (-inf where it is 0)."""
    k = P.shape[0]
    m = mu.shape[0]
    log_U = -3.0 * math.log(2.0 * v_b)
    c = -1.5 * _LOG_2PI
    out = np.empty(k)
    mean = np.empty(3)
    for i in range(k):
        r = 0
        for j in range(m):
            if kernel_reachable(mu, j, P, i, dt, v_b, sd):
                r += 1
        if r > 0 and u_aim[i] >= blind:
            target = int(math.floor(u_pick[i] * r))
            seen = 0
            for j in range(m):
                if not kernel_reachable(mu, j, P, i, dt, v_b, sd):
                    continue
                if seen == target:
                    for a in range(3):
                        acc = (mu[j, a] - P[i, a]) / dt
                        for b in range(a + 1):
                            acc += chol[j, a, b] * xi[i, b]
                        V[i, a] = acc
                    break
                seen += 1
        inside = abs(V[i, 0]) <= v_b and abs(V[i, 1]) <= v_b and abs(V[i, 2]) <= v_b
        log_blind = -np.inf
        if inside:
            log_blind = log_U + (math.log(blind) if r > 0 else 0.0)
        if r == 0:
            out[i] = log_blind
            continue
        mx = -np.inf
        acc_s = 0.0
        for j in range(m):
            ok = True  # kernel_reachable, keeping the velocity (mu_j - p) / dt for the density
            for a in range(3):
                mean[a] = (mu[j, a] - P[i, a]) / dt
                if abs(mean[a]) > v_b + 3.0 * sd[j, a]:
                    ok = False
            if not ok:
                continue
            q = 0.0
            for a in range(3):
                y = 0.0
                for b in range(a + 1):
                    y += Linv[j, a, b] * (V[i, b] - mean[b])
                q += y * y
            t = c - log_det[j] - 0.5 * q
            if t > mx:
                acc_s = _scaled(acc_s, mx - t) + 1.0
                mx = t
            else:
                acc_s = _add_exp(acc_s, t - mx)
        log_aimed = math.log(1.0 - blind) + mx + math.log(acc_s) - math.log(r)
        hi = max(log_blind, log_aimed)
        out[i] = hi + _log1p_exp(min(log_blind, log_aimed) - hi) if hi > -np.inf else -np.inf
    return out


@njit(cache=True)
def kernel_young_weights(V, v_b, log_U, log_L, log_qp, log_qv):
    """The two-scan proposal's weights (estimation/birth.py ``redraw_young``) in one pass: per row
    ``log_U + log_L - log_qp - log_qv`` where every velocity component of ``V`` (k, 3) lies within
    ``±v_b`` and ``log_qp`` is finite, else -inf; the numpy expression it replaces, bit for bit."""
    k = V.shape[0]
    out = np.empty(k)
    for i in range(k):
        ok = abs(V[i, 0]) <= v_b and abs(V[i, 1]) <= v_b and abs(V[i, 2]) <= v_b
        lp = log_qp[i]
        if ok and math.isfinite(lp):
            out[i] = log_U + log_L[i] - lp - log_qv[i]
        else:
            out[i] = -np.inf
    return out


MODE_MAX_CELLS = 1 << 21  # the mode's grid: its cell doubles until the particles' box holds at most this many
MODE_MAX_INDEX = 2.0**52  # and until every cell index is an exact integer of float64 (and of int64)
MODE_SHIFTS = 4  # mean-shift steps from the heaviest cell (filter.mode)


@njit(cache=True)
def _mode_grid(X, cell):
    """The grid of :func:`kernel_mode_cluster`: cell size (doubled from ``cell`` until the box of
    the particles' positions holds at most MODE_MAX_CELLS cells and every cell index lies within
    +-MODE_MAX_INDEX), the box's lowest cell index and its cell counts.

    The counts are multiplied in float64: a tiny ``filter.mode.radius`` (1e-5 m) over a box of
    100 m gives 1e7 cells a side, whose product overflowed int64 to a negative count that passed
    the cap; the index bound keeps a cell index of 1e5 m / 1e-300 m from overflowing too."""
    lo = np.empty(3, dtype=np.int64)
    dims = np.empty(3, dtype=np.int64)
    mn = np.empty(3)
    mx = np.empty(3)
    for a in range(3):
        mn[a] = X[0, a]
        mx[a] = X[0, a]
    for i in range(1, X.shape[0]):
        for a in range(3):
            mn[a] = min(mn[a], X[i, a])
            mx[a] = max(mx[a], X[i, a])
    low = np.empty(3)
    high = np.empty(3)
    cell = max(cell, 5e-324)  # a cell of 0 (0.5 x 5e-324 rounds to it) would never grow
    while True:
        total = 1.0
        index = 0.0
        for a in range(3):
            low[a] = math.floor(mn[a] / cell)
            high[a] = math.floor(mx[a] / cell)
            total *= high[a] - low[a] + 1.0
            index = max(index, abs(low[a]), abs(high[a]))
        # past an infinite cell nothing shrinks further: non-finite positions, which no filter makes
        if (total <= MODE_MAX_CELLS and index <= MODE_MAX_INDEX) or cell == math.inf:
            for a in range(3):
                lo[a] = int(low[a])
                dims[a] = int(high[a] - low[a] + 1.0)
            return cell, lo, dims
        cell *= 2.0


@njit(cache=True)
def kernel_mode_cluster(X, w, radius, cell):
    """The densest cluster of particles ``X`` (n, >= 3) with weights ``w`` (n,): the weighted
    mean of the particles in the heaviest cell of a grid of ``cell`` metres (cells at multiples
    of the cell size; a box too large for MODE_MAX_CELLS cells doubles it), moved MODE_SHIFTS
    times to the weighted mean of the particles within ``radius`` of it (mean shift with a flat
    kernel). Returns (centre (3,), the weight within ``radius`` of it, that mask (n,) bool).
    Ties between cells go to the first in x-major order. Plain-numpy twin:
    ``trackjam.estimation.bernoulli.mode_cluster_reference``. ``n`` >= 1: with no particle the
    grid's box reads ``X[0]`` out of bounds (no check here; its wrapper
    :func:`~trackjam.estimation.bernoulli.mode_moments` refuses an empty set)."""
    n = X.shape[0]
    cell, lo, dims = _mode_grid(X, cell)
    grid = np.zeros(dims[0] * dims[1] * dims[2])
    idx = np.empty(n, dtype=np.int64)
    for i in range(n):
        ix = int(math.floor(X[i, 0] / cell)) - lo[0]
        iy = int(math.floor(X[i, 1] / cell)) - lo[1]
        iz = int(math.floor(X[i, 2] / cell)) - lo[2]
        idx[i] = (ix * dims[1] + iy) * dims[2] + iz
        grid[idx[i]] += w[i]
    best = 0
    for k in range(1, grid.shape[0]):
        if grid[k] > grid[best]:
            best = k
    centre = np.zeros(3)
    sw = 0.0
    for i in range(n):
        if idx[i] == best:
            sw += w[i]
            for a in range(3):
                centre[a] += w[i] * X[i, a]
    if sw > 0.0:
        centre /= sw
    else:  # every weight is 0: the heaviest cell is the first; its plain mean
        c = 0
        for i in range(n):
            if idx[i] == best:
                c += 1
                for a in range(3):
                    centre[a] += X[i, a]
        centre /= max(c, 1)
    r2 = radius * radius
    inside = np.zeros(n, dtype=np.bool_)
    mass = 0.0
    for step in range(MODE_SHIFTS + 1):
        acc = np.zeros(3)
        mass = 0.0
        changed = False
        for i in range(n):
            d2 = 0.0
            for a in range(3):
                d = X[i, a] - centre[a]
                d2 += d * d
            now = d2 < r2
            if now != inside[i]:
                changed = True
                inside[i] = now
            if now:
                mass += w[i]
                for a in range(3):
                    acc[a] += w[i] * X[i, a]
        if step == MODE_SHIFTS or mass <= 0.0:
            break
        if step > 0 and not changed:  # the same particles as the last pass: centre is their mean already
            break
        centre = acc / mass
    return centre, mass, inside


@njit(cache=True)
def kernel_masked_moments(X, w, inside, mass):
    """Mean (6,) and covariance (6, 6) of the particles ``X`` (n, 6) where ``inside``, with weights
    ``w / mass`` (``mass``: their weights' sum); :func:`kernel_weighted_moments` of that subset
    without copying it."""
    return _moments(X, w, inside, mass)
