"""Data association of the labelled multi-Bernoulli update (Reuter, Vo, Vo & Dietmayer 2014,
Sec. III; Vo, Vo & Hoang 2017 for the Gibbs sampler).

Tracks i = 0..T-1 with existence r_i and spatial density s_i, measurements j = 0..m-1 of one
scan. A joint hypothesis gamma gives each track a column: 0 (undetected: absent, or present
and missed) or 1 + j (it made measurement j), no measurement used twice. Its weight is
prod_i eta[i, gamma_i] with

    eta[i, 0]     = 1 - r_i + r_i ∫ (1 - p_D) s_i,
    eta[i, 1 + j] = r_i ∫ p_D g(y_j | x) / (lambda_c p_c(y_j)) s_i.

What the LMB update needs are the marginals ``beta[i, c]``: the normalised weight of the
hypotheses with gamma_i = c. Enumerating every hypothesis grows like (m + 1)^T; here the
hypotheses are either sampled (Gibbs) or ranked (Murty's k best, each a linear assignment), and
the marginals are taken over the distinct hypotheses found, each with its exact weight.
"""

from __future__ import annotations

import heapq
import itertools

import numpy as np
from numba import njit
from scipy.optimize import linear_sum_assignment

# the undetected weight is floored so that some hypothesis is always possible: eta[i, 0] is 0
# only for a track certain to exist under a detection probability of exactly 1
LOG_FLOOR = -700.0


def _floored(log_eta: np.ndarray) -> np.ndarray:
    log_eta = np.array(log_eta, dtype=float)
    log_eta[:, 0] = np.maximum(log_eta[:, 0], LOG_FLOOR)
    return log_eta


def assignment_costs(log_eta: np.ndarray) -> np.ndarray:
    """The linear-assignment form (T, m + T): column j < m is measurement j, column m + i is
    track i undetected (only for row i); cost -log eta, inf where forbidden."""
    T, m1 = log_eta.shape
    m = m1 - 1
    C = np.full((T, m + T), np.inf)
    C[:, :m] = -log_eta[:, 1:]
    C[np.arange(T), m + np.arange(T)] = -log_eta[:, 0]
    return C


def _hypothesis(cols: np.ndarray, m: int) -> np.ndarray:
    return np.where(cols < m, cols + 1, 0).astype(np.int64)


def best_hypothesis(log_eta: np.ndarray) -> np.ndarray:
    """The most likely joint hypothesis (T,), by one linear assignment."""
    log_eta = _floored(log_eta)
    _, cols = linear_sum_assignment(assignment_costs(log_eta))
    return _hypothesis(cols, log_eta.shape[1] - 1)


@njit(cache=True)
def kernel_gibbs(log_eta, start, uniforms):
    """Gibbs sampling of joint hypotheses: sweep ``s`` redraws each track's column in turn from
    its conditional given the others' (proportional to eta[i, c] over column 0 and the
    measurements no other track holds), using ``uniforms[s, i]``. Returns (S, T) columns."""
    S, T = uniforms.shape
    m = log_eta.shape[1] - 1
    out = np.empty((S, T), dtype=np.int64)
    g = start.copy()
    used = np.zeros(m, dtype=np.int64)
    for i in range(T):
        if g[i] > 0:
            used[g[i] - 1] += 1
    p = np.empty(m + 1)
    for s in range(S):
        for i in range(T):
            if g[i] > 0:
                used[g[i] - 1] -= 1
            mx = -np.inf
            for c in range(m + 1):
                v = log_eta[i, c] if (c == 0 or used[c - 1] == 0) else -np.inf
                p[c] = v
                if v > mx:
                    mx = v
            total = 0.0
            for c in range(m + 1):
                p[c] = np.exp(p[c] - mx) if p[c] > -np.inf else 0.0
                total += p[c]
            pick = uniforms[s, i] * total
            choice = 0
            acc = 0.0
            for c in range(m + 1):
                if p[c] > 0.0:
                    choice = c
                    acc += p[c]
                    if pick < acc:
                        break
            g[i] = choice
            if choice > 0:
                used[choice - 1] += 1
        out[s] = g
    return out


def unique_rows(a: np.ndarray) -> np.ndarray:
    """The distinct rows of an integer array (H, T) in lexicographic order: ``np.unique(a,
    axis=0)``, which sorts structured records, more than ten times slower on the sweeps."""
    if len(a) == 0 or a.shape[1] == 0:
        return a[: min(len(a), 1)]
    s = a[np.lexsort(a.T[::-1])]
    keep = np.ones(len(s), dtype=bool)
    keep[1:] = np.any(s[1:] != s[:-1], axis=1)
    return s[keep]


def gibbs_hypotheses(log_eta: np.ndarray, samples: int, rng: np.random.Generator,
                     misses: bool = False) -> np.ndarray:
    """Distinct joint hypotheses (H, T) visited by ``samples`` Gibbs sweeps started at the best
    one (which is therefore always among them). With ``misses`` (``filter.association_misses``,
    ours) also, for each track, the best hypothesis with that track's detection missed: a sampler
    that never visits a track's miss (a confident detection makes it about e^-7 as likely) sets
    its existence to exactly 1, which no later scan of the step can lower."""
    log_eta = _floored(log_eta)
    start = best_hypothesis(log_eta)
    drawn = kernel_gibbs(log_eta, start, rng.random((samples, len(log_eta))))
    rows = [start[None, :], drawn]
    if misses:
        missed = np.repeat(start[None, :], len(start), axis=0)
        missed[np.arange(len(start)), np.arange(len(start))] = 0  # freeing a measurement keeps it a hypothesis
        rows.append(missed)
    return unique_rows(np.vstack(rows))


def _solve(C: np.ndarray):
    try:
        rows, cols = linear_sum_assignment(C)
    except ValueError:  # no assignment avoids the forbidden entries
        return None
    cost = float(C[rows, cols].sum())
    return (cost, cols) if np.isfinite(cost) else None


def ranked_hypotheses(log_eta: np.ndarray, k: int) -> np.ndarray:
    """The ``k`` most likely joint hypotheses (fewer when fewer exist), best first, by Murty's
    partition of the assignment problem: each solution's subproblem is split into one child per
    row, the child forbidding that row's column and keeping the rows before it fixed."""
    log_eta = _floored(log_eta)
    T, m1 = log_eta.shape
    m = m1 - 1
    root = assignment_costs(log_eta)
    first = _solve(root)
    tie = itertools.count()
    heap = [(first[0], next(tie), root, first[1])]
    found = []
    while heap and len(found) < k:
        _, _, C, cols = heapq.heappop(heap)
        found.append(_hypothesis(cols, m))
        fixed = C.copy()
        for i in range(T):
            child = fixed.copy()
            child[i, cols[i]] = np.inf
            sol = _solve(child)
            if sol is not None:
                heapq.heappush(heap, (sol[0], next(tie), child, sol[1]))
            keep = fixed[i, cols[i]]
            fixed[i, :] = np.inf
            fixed[:, cols[i]] = np.inf
            fixed[i, cols[i]] = keep
    return np.array(found, dtype=np.int64).reshape(-1, T)


def hypothesis_log_weights(log_eta: np.ndarray, hyps: np.ndarray) -> np.ndarray:
    """log prod_i eta[i, gamma_i] of each hypothesis (H, T)."""
    return np.asarray(log_eta, dtype=float)[np.arange(hyps.shape[1]), hyps].sum(axis=1)


def marginals(log_eta: np.ndarray, hyps: np.ndarray) -> np.ndarray:
    """beta (T, m + 1): the marginals of the joint hypotheses ``hyps`` (H, T), weighted exactly
    and normalised over them."""
    log_eta = _floored(log_eta)
    log_w = hypothesis_log_weights(log_eta, hyps)
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    T = log_eta.shape[0]
    beta = np.zeros(log_eta.shape)
    np.add.at(beta, (np.broadcast_to(np.arange(T), hyps.shape), hyps), w[:, None])
    return beta


def association_marginals(log_eta: np.ndarray, method: str, rng: np.random.Generator, samples: int = 1000,
                          k: int = 200, misses: bool = False) -> np.ndarray:
    """beta of the LMB update by ``method``: ``gibbs`` (``samples`` sweeps, with ``misses`` each
    track's miss of the best hypothesis too, :func:`gibbs_hypotheses`) or ``ranked`` (the ``k``
    best hypotheses)."""
    log_eta = np.asarray(log_eta, dtype=float)
    if log_eta.shape[0] == 0:
        return np.zeros(log_eta.shape)
    if method == "gibbs":
        hyps = gibbs_hypotheses(log_eta, samples, rng, misses)
    elif method == "ranked":
        hyps = ranked_hypotheses(log_eta, k)
    else:
        raise ValueError(f"unknown association method {method!r}")
    return marginals(log_eta, hyps)
