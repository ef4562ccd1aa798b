"""Compiled hot loops of the LMB filter (estimation/lmb.py): per particle and measurement the
factors of the association weights, and per track the means and posterior weights of its
particles. ``tests/estimation/test_lmb_kernels.py`` holds each to a plain-numpy twin."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from trackjam.estimation.kernels import kernel_gated_log_g
from trackjam.radio.antenna import kernel_cone_gain

_LOG_2PI = math.log(2.0 * math.pi)


@njit(cache=True, inline="always")
def _exp(d):
    """exp(d), skipping the call at d = 0 (exp(0) = 1 exactly): the particles outside the cone
    share one log-weight, which is often the largest, so most terms of their sums are exp(0)."""
    return 1.0 if d == 0.0 else math.exp(d)


@njit(cache=True)
def kernel_ball(X):
    """Centre (3,) and radius [m] of a ball holding every particle's position: the mean and the
    largest distance from it."""
    n = X.shape[0]
    c = np.zeros(3)
    for i in range(n):
        for k in range(3):
            c[k] += X[i, k]
    if n > 0:
        c /= n
    r2 = 0.0
    for i in range(n):
        d2 = (X[i, 0] - c[0]) ** 2 + (X[i, 1] - c[1]) ** 2 + (X[i, 2] - c[2]) ** 2
        if d2 > r2:
            r2 = d2
    return c, math.sqrt(r2)


@njit(cache=True)
def kernel_beyond_cone(centre, radius, u, axis, height, tan_half, margin):
    """True when no point of the ball (``centre``, ``radius``) can lie in the cone (apex ``u``,
    unit ``axis``, height, tan of the half-angle): the ball lies more than ``margin`` [m] beyond
    its base, behind its apex or outside its side. The side's test is f(x) = |x_perp| cos(theta)
    - s sin(theta) > margin (s along the axis, x_perp across), and f is 1-Lipschitz, so
    f(centre) - radius > margin holds f > margin at every point of the ball."""
    dx = centre[0] - u[0]
    dy = centre[1] - u[1]
    dz = centre[2] - u[2]
    s = dx * axis[0] + dy * axis[1] + dz * axis[2]
    if s + radius < -margin or s - radius > height + margin:
        return True
    px = dx - s * axis[0]
    py = dy - s * axis[1]
    pz = dz - s * axis[2]
    cos_t = 1.0 / math.sqrt(1.0 + tan_half * tan_half)
    return math.sqrt(px * px + py * py + pz * pz) * cos_t - s * tan_half * cos_t - radius > margin


@njit(cache=True)
def kernel_seen_factors(X, Z, u, axis, p_d_scale, height, tan_half, r0, n_e, noise_std, log_kappa):
    """The particles with p_D > 0 (``seen`` (k,), indices ascending), their ``p_D`` (k,) and, per
    measurement, ``log g(y_j | x_i) - log kappa`` (k, m), kappa = lambda_c p_c; -inf where y_j
    lies GATE standard deviations or more away (:func:`kernel_gated_log_g`, the gating of
    ``kernel_update_factors``, whose log L_i is log(1 - p_D + p_D sum_j exp(.)) of these).
    Particles outside the cone (most of a track's, for most scans) are only counted out: nothing
    is written for them."""
    n = X.shape[0]
    m = Z.shape[0]
    seen = np.empty(n, dtype=np.int64)
    p_d = np.empty(n)
    out = np.empty((n, m))
    s0, s1, s2 = noise_std[0], noise_std[1], noise_std[2]
    c_max = -1.5 * _LOG_2PI - math.log(s0) - math.log(s1) - math.log(s2) - log_kappa
    k = 0
    for i in range(n):
        pd = p_d_scale * kernel_cone_gain(
            X[i, 0], X[i, 1], X[i, 2], u[0], u[1], u[2], axis[0], axis[1], axis[2], height, tan_half, r0, n_e
        )
        if pd <= 0.0:
            continue
        seen[k] = i
        p_d[k] = pd
        kernel_gated_log_g(X, i, u, Z, s0, s1, s2, c_max, out, k)
        k += 1
    return seen[:k], p_d[:k], out[:k]


@njit(cache=True)
def kernel_association_factors(X, Z, u, axis, p_d_scale, height, tan_half, r0, n_e, noise_std, log_kappa):
    """Per particle ``p_D`` (n,) and per particle and measurement ``log g(y_j | x_i) - log
    kappa`` (n, m): :func:`kernel_seen_factors` spread over every particle (p_D = 0 and -inf
    outside the cone)."""
    seen, p_seen, g_seen = kernel_seen_factors(X, Z, u, axis, p_d_scale, height, tan_half, r0, n_e, noise_std,
                                               log_kappa)
    p_d = np.zeros(X.shape[0])
    out = np.full((X.shape[0], Z.shape[0]), -np.inf)
    for k in range(seen.shape[0]):
        p_d[seen[k]] = p_seen[k]
        out[seen[k]] = g_seen[k]
    return p_d, out


@njit(cache=True)
def kernel_log_means(log_w, seen, log_miss, log_p_d, log_g):
    """log <f_c> = log sum_i w_i f_c(x_i) per column c of a track's factors at the particles
    ``seen`` (ascending) with p_D > 0: f_0 = 1 - p_D (``log_miss`` (k,)), f_{1+j} = p_D g(y_j |
    x) / kappa (``log_p_d`` (k,) + ``log_g`` (k, m)); every other particle has f_0 = 1 and adds
    to column 0 only."""
    n = log_w.shape[0]
    k, m = log_g.shape
    mx = np.full(m + 1, -np.inf)
    s = 0
    for i in range(n):
        if s < k and seen[s] == i:
            v = log_w[i] + log_miss[s]
            for j in range(m):
                g = log_w[i] + (log_p_d[s] + log_g[s, j])
                if g > mx[1 + j]:
                    mx[1 + j] = g
            s += 1
        else:
            v = log_w[i]
        if v > mx[0]:
            mx[0] = v
    acc = np.zeros(m + 1)
    s = 0
    for i in range(n):
        if s < k and seen[s] == i:
            v = log_w[i] + log_miss[s]
            for j in range(m):
                g = log_w[i] + (log_p_d[s] + log_g[s, j])
                if g > -np.inf:
                    acc[1 + j] += math.exp(g - mx[1 + j])
            s += 1
        else:
            v = log_w[i]
        if v > -np.inf:
            acc[0] += _exp(v - mx[0])
    out = np.empty(m + 1)
    for c in range(m + 1):
        out[c] = -np.inf if mx[c] == -np.inf else mx[c] + math.log(acc[c])
    return out


@njit(cache=True)
def kernel_mixture_log_weights(log_w, seen, log_miss, log_p_d, log_g, coef):
    """Normalised log of w_i sum_c f_c(x_i) exp(coef[c]) over the columns with a finite
    ``coef`` (the factors f_c of :func:`kernel_log_means`): the posterior weights of a track's
    particles."""
    n = log_w.shape[0]
    k, m = log_g.shape
    out = np.empty(n)
    top = -np.inf  # the largest of out, for the normalisation
    s = 0
    for i in range(n):
        if not (s < k and seen[s] == i):  # f_0 = 1 only: the sum is exp(coef[0])
            out[i] = log_w[i] + coef[0]
            if out[i] > top:
                top = out[i]
            continue
        mx = -np.inf
        if coef[0] > -np.inf:
            mx = log_miss[s] + coef[0]
        for j in range(m):
            if coef[1 + j] > -np.inf:
                v = (log_p_d[s] + log_g[s, j]) + coef[1 + j]
                if v > mx:
                    mx = v
        if mx == -np.inf:
            out[i] = -np.inf
        else:
            acc = 0.0
            if coef[0] > -np.inf:
                v = log_miss[s] + coef[0]
                if v > -np.inf:
                    acc += math.exp(v - mx)
            for j in range(m):
                if coef[1 + j] > -np.inf:
                    v = (log_p_d[s] + log_g[s, j]) + coef[1 + j]
                    if v > -np.inf:
                        acc += math.exp(v - mx)
            out[i] = log_w[i] + mx + math.log(acc)
            if out[i] > top:
                top = out[i]
        s += 1
    acc = 0.0
    for i in range(n):
        if out[i] > -np.inf:
            acc += _exp(out[i] - top)
    total = top + math.log(acc)
    for i in range(n):
        out[i] -= total
    return out
