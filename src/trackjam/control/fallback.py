"""What the team does when nobody believes in the target (docs/model.md, Control; ours).

No planning aim exists (no agent has e_{t|t-1} > 0.5), so every agent hovers and keeps its last
aim, and transmits at the highest level Eq. (13) allows. "Highest" for a team is made precise
as (ours): maximise the total transmitted power sum_j l_j [W]; among equal totals take the
level vector that is largest lexicographically, so lower agent indices get the higher levels.
With constraints off every agent transmits at l_max.

``kernel_fallback_levels`` is a depth-first branch and bound over the agents (levels tried
from the highest down, cut when even l_max for every remaining agent cannot beat the best
total). ``fallback_levels_reference`` is the brute force over all |L|^N level vectors.
Totals are computed from the number of agents at each level, so equal multisets of levels give
bit-equal totals and ties are exact.
"""

from __future__ import annotations

import itertools

import numpy as np
from numba import njit

from trackjam.radio.antenna import AntennaModel, interference_matrix


def hover_gains(positions, aims, antenna: AntennaModel) -> np.ndarray:
    """``G[i, j]``: path gain of agent j's cone (aimed at ``aims[j]``) at agent i; 0 diagonal."""
    u = np.atleast_2d(np.asarray(positions, dtype=np.float64))
    return interference_matrix(u, aims, np.ones(u.shape[0]), antenna)


@njit(cache=True)
def _total(counts, levels_w):
    t = 0.0
    for l in range(levels_w.shape[0]):
        t += counts[l] * levels_w[l]
    return t


@njit(cache=True)
def kernel_fallback_levels(G, levels_w, delta, constrained, best_level):
    """Levels maximising total power under Eq. (13) (ties: lexicographically largest).

    ``best_level`` (N,) receives the answer; returns its total [W].
    """
    N = G.shape[0]
    L = levels_w.shape[0]
    lv = np.zeros(N, dtype=np.int64)
    cur = np.full(N, L, dtype=np.int64)  # next level to try is cur - 1
    counts = np.zeros(L, dtype=np.int64)
    recv = np.zeros((N + 1, N))  # recv[d + 1, i]: power at i from agents 0..d
    best = -1.0
    d = 0
    while d >= 0:
        if cur[d] == 0:
            cur[d] = L
            d -= 1
            if d >= 0:
                counts[lv[d]] -= 1
            continue
        cur[d] -= 1
        l = cur[d]
        counts[l] += 1
        counts[L - 1] += N - 1 - d
        bound = _total(counts, levels_w)
        counts[L - 1] -= N - 1 - d
        if bound <= best:
            counts[l] -= 1
            cur[d] = 0  # lower levels give lower bounds
            continue
        ok = True
        if constrained:
            inc = 0.0
            for j in range(d):
                inc += levels_w[lv[j]] * G[d, j]
            if inc >= delta:
                ok = False
            for j in range(d):
                recv[d + 1, j] = recv[d, j] + levels_w[l] * G[j, d]
                if recv[d + 1, j] >= delta:
                    ok = False
            recv[d + 1, d] = inc
        if not ok:
            counts[l] -= 1
            continue
        lv[d] = l
        if d == N - 1:
            best = bound
            best_level[:] = lv
            counts[l] -= 1
            cur[d] = 0
            continue
        d += 1
    return best


def fallback_levels(positions, aims, antenna: AntennaModel, constraints: bool) -> np.ndarray:
    """Level indices (N,) of hovering agents aimed at ``aims`` (N, 3): the highest total power
    Eq. (13) allows, ties to lower agent indices (see the module docstring)."""
    G = hover_gains(positions, aims, antenna)
    levels_w = np.asarray(antenna.levels_w, dtype=np.float64)
    out = np.zeros(G.shape[0], dtype=np.int64)
    kernel_fallback_levels(G, levels_w, float(antenna.delta_w), bool(constraints), out)
    return out


def fallback_levels_reference(positions, aims, antenna: AntennaModel, constraints: bool) -> np.ndarray:
    """Brute force over all |L|^N level vectors, in lexicographically descending order."""
    G = hover_gains(positions, aims, antenna)
    levels_w = np.asarray(antenna.levels_w, dtype=np.float64)
    N, L = G.shape[0], levels_w.shape[0]
    best, best_lv = -1.0, np.zeros(N, dtype=np.int64)
    for lv in itertools.product(range(L - 1, -1, -1), repeat=N):
        lv = np.array(lv)
        if constraints and np.any(G @ levels_w[lv] >= antenna.delta_w):
            continue
        total = float(_total(np.bincount(lv, minlength=L), levels_w))
        if total > best:
            best, best_lv = total, lv
    return best_lv
