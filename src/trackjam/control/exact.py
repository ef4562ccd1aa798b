"""The proven optimum of Eqs. (12)-(13) by branch and bound (ours, beyond the paper).

Agents are assigned in index order 0..N-1; each agent's (candidate, level) pairs are tried in
the order p_D descending, then lower level, then lower displacement index. Two facts make the
search exact and fast:

- Xi^N_n is non-decreasing in every p^j_D, so the value of any completion of a partial
  assignment is at most Xi with every unassigned agent at its best *still admissible* p_D;
- interference only grows as agents are added (gains and levels are >= 0), so a pair that
  breaks Eq. (13) against the agents already placed is useless in every completion, and an
  agent with no such pair left ends the branch (forward checking).

A branch is cut when its bound is <= the incumbent, and the incumbent is replaced only by a
strictly better value. The incumbent starts as every agent hovering at the lowest level (off,
0 W: always feasible), so the result is that when no joint control beats it; otherwise it is
the first optimum in the search order above (ties are exact floating-point ties).

``enumerate_optimum`` is the plain-numpy full enumeration the tests hold the kernel to.
"""

from __future__ import annotations

import itertools

import numpy as np
from numba import njit

from trackjam.control.objective import evaluate, kernel_at_least, kernel_feasible, to_solution
from trackjam.control.problem import Problem, Solution


def pair_order(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Each agent's pairs k = c * L + l, ranked by p_D descending, then level, then move.

    Returns ``order`` (N, C*L) padded with -1, and ``n_pairs`` (N,).
    """
    N, C, L = problem.p_d.shape
    order = np.full((N, C * L), -1, dtype=np.int64)
    n_pairs = problem.n_cand * L
    for i in range(N):
        n = int(problem.n_cand[i])
        c, l = np.divmod(np.arange(n * L), L)
        p = problem.p_d[i, c, l]
        rank = np.lexsort((c, l, -p))  # last key is primary
        order[i, : n * L] = c[rank] * L + l[rank]
    return order, n_pairs


_ONE = np.uint64(1)
_ZERO = np.uint64(0)
_ALL = ~np.uint64(0)
_DEBRUIJN = np.uint64(0x03F79D71B4CB0A89)
_CTZ = np.zeros(64, dtype=np.int64)
for _b in range(64):
    _CTZ[((1 << _b) * 0x03F79D71B4CB0A89 % (1 << 64)) >> 58] = _b


@njit(cache=True)
def _ctz(m):
    """Index of the lowest set bit of a non-zero uint64."""
    low = m & (~m + _ONE)
    return _CTZ[np.int64((low * _DEBRUIJN) >> np.uint64(58))]


@njit(cache=True)
def _admissible(k, ck, lk, d, gain, levels_w, delta, c, lv, recv):
    """Whether agent ``k`` at (ck, lk) keeps Eq. (13) against agents 0..d already placed."""
    inc = 0.0
    for j in range(d + 1):
        inc += levels_w[lv[j]] * gain[k, j, ck, c[j]]
    if inc >= delta:
        return False
    for j in range(d + 1):
        if recv[d, j] + levels_w[lk] * gain[j, k, c[j], ck] >= delta:
            return False
    return True


@njit(cache=True)
def _pair_row(j, rj, rank_c, rank_l, n_pairs, gain, levels_w, delta, rows):
    """Bitsets ``rows[j, rj, k]`` (k > j): ranks of agent k compatible, pair by pair, with
    agent j at rank rj (neither puts delta or more on the other)."""
    N = n_pairs.shape[0]
    cj = rank_c[j, rj]
    wj = levels_w[rank_l[j, rj]]
    for k in range(j + 1, N):
        for rk in range(n_pairs[k]):
            ck = rank_c[k, rk]
            if wj * gain[k, j, ck, cj] < delta and levels_w[rank_l[k, rk]] * gain[j, k, cj, ck] < delta:
                rows[j, rj, k, rk >> 6] |= _ONE << np.uint64(rk & 63)


@njit(cache=True)
def _first_admissible(k, start, d, rank, rank_c, rank_l, n_pairs, rows, gain, levels_w, delta, c, lv, recv):
    """First rank >= ``start`` of agent k admissible against agents 0..d (n_pairs[k] if none).

    Candidates come from the AND of the pairwise bitsets; the exact sum of Eq. (13) is checked
    on each (pairwise compatibility is necessary, and sufficient when d == 0)."""
    W = rows.shape[3]
    w = start >> 6
    while w < W and w * 64 < n_pairs[k]:
        m = _ALL
        for j in range(d + 1):
            m &= rows[j, rank[j], k, w]
        if w == start >> 6:
            m &= _ALL << np.uint64(start & 63)
        while m != _ZERO:
            r = w * 64 + _ctz(m)
            if r >= n_pairs[k]:
                return n_pairs[k]
            if d == 0 or _admissible(k, rank_c[k, r], rank_l[k, r], d, gain, levels_w, delta, c, lv, recv):
                return r
            m &= m - _ONE
        w += 1
    return n_pairs[k]


@njit(cache=True)
def kernel_branch_and_bound(p_d, gain, levels_w, delta, n, constrained, order, n_pairs,
                            best_cand, best_level, max_nodes):
    """Maximise Xi^N_n subject to Eq. (13) (when ``constrained``).

    ``best_cand``/``best_level`` (N,) hold the starting incumbent on entry and the optimum on
    exit. Returns (value, nodes visited, proven): value is -inf when nothing feasible was
    found; ``proven`` is False only when ``max_nodes`` > 0 stopped the search early (then the
    incumbent is the best found so far).
    """
    N = p_d.shape[0]
    L = levels_w.shape[0]
    P = order.shape[1]
    q = np.empty(n + 1)
    pv = np.empty(N)
    ps = np.zeros((N, P))  # p_D of each ranked pair
    rank_c = np.zeros((N, P), dtype=np.int64)
    rank_l = np.zeros((N, P), dtype=np.int64)
    for i in range(N):
        for r in range(n_pairs[i]):
            kk = order[i, r]
            rank_c[i, r] = kk // L
            rank_l[i, r] = kk % L
            ps[i, r] = p_d[i, rank_c[i, r], rank_l[i, r]]
    W = (P + 63) // 64 if constrained else 1
    rows = np.zeros((N if constrained else 1, P if constrained else 1, N, W), dtype=np.uint64)
    have = np.zeros((N, P), dtype=np.bool_)
    c = np.zeros(N, dtype=np.int64)
    lv = np.zeros(N, dtype=np.int64)
    rank = np.zeros(N, dtype=np.int64)
    p = np.zeros(N)
    recv = np.zeros((N, N))  # recv[d, j]: power at agent j from agents 0..d
    bptr = np.zeros((N + 1, N), dtype=np.int64)  # first admissible rank of agent k given 0..d-1
    cur = np.zeros(N, dtype=np.int64)

    for i in range(N):
        pv[i] = p_d[i, best_cand[i], best_level[i]]
    best = kernel_at_least(pv, n, q)
    if constrained and not kernel_feasible(gain, levels_w, delta, best_cand, best_level):
        best = -np.inf

    nodes = 0
    d = 0
    cur[0] = 0
    while d >= 0:
        descended = False
        while cur[d] < n_pairs[d]:
            r = cur[d]
            if constrained and d > 0:
                r = _first_admissible(d, r, d - 1, rank, rank_c, rank_l, n_pairs, rows, gain,
                                      levels_w, delta, c, lv, recv)
                if r == n_pairs[d]:
                    cur[d] = r
                    break
            cur[d] = r + 1
            nodes += 1
            if max_nodes > 0 and nodes > max_nodes:
                return best, nodes, False
            for j in range(d):
                pv[j] = p[j]
            pv[d] = ps[d, r]
            for k in range(d + 1, N):
                pv[k] = ps[k, bptr[d, k]]
            bound = kernel_at_least(pv, n, q)
            if bound <= best:
                cur[d] = n_pairs[d]  # later pairs of agent d have lower or equal p_D
                break
            c[d] = rank_c[d, r]
            lv[d] = rank_l[d, r]
            rank[d] = r
            p[d] = ps[d, r]
            if constrained:
                inc = 0.0
                for j in range(d):
                    inc += levels_w[lv[j]] * gain[d, j, c[d], c[j]]
                    recv[d, j] = recv[d - 1, j] + levels_w[lv[d]] * gain[j, d, c[j], c[d]]
                recv[d, d] = inc
            if d == N - 1:
                best = bound
                best_cand[:] = c
                best_level[:] = lv
                cur[d] = n_pairs[d]
                break
            if constrained and not have[d, r]:
                _pair_row(d, r, rank_c, rank_l, n_pairs, gain, levels_w, delta, rows)
                have[d, r] = True
            dead = False
            for k in range(d + 1, N):
                rr = bptr[d, k]
                if constrained:
                    rr = _first_admissible(k, rr, d, rank, rank_c, rank_l, n_pairs, rows, gain,
                                           levels_w, delta, c, lv, recv)
                if rr == n_pairs[k]:
                    dead = True
                    break
                bptr[d + 1, k] = rr
                pv[k] = ps[k, rr]
            if dead:
                continue
            pv[d] = p[d]
            if kernel_at_least(pv, n, q) <= best:
                continue
            d += 1
            cur[d] = bptr[d, d]
            descended = True
            break
        if not descended:
            d -= 1
    return best, nodes, True


def solve_exact(problem: Problem) -> Solution:
    """The optimum of Eqs. (12)-(13) (of Eq. 12 alone when constraints are off)."""
    order, n_pairs = pair_order(problem)
    N = problem.n_agents
    cand = np.zeros(N, dtype=np.int64)
    level = np.zeros(N, dtype=np.int64)
    kernel_branch_and_bound(
        problem.p_d, problem.gain, problem.levels_w, problem.delta_w, problem.at_least,
        problem.constraints, order, n_pairs, cand, level, 0,
    )
    return to_solution(problem, cand, level)


def enumerate_optimum(problem: Problem) -> tuple[float, np.ndarray, np.ndarray]:
    """Plain-numpy full enumeration in the branch-and-bound's order (small instances only).

    Returns (value, candidate slots, levels), with the same starting incumbent and ties.
    """
    order, n_pairs = pair_order(problem)
    N, L = problem.n_agents, problem.n_levels
    ranks = np.array(list(itertools.product(*[range(int(m)) for m in n_pairs])), dtype=np.int64)
    kk = order[np.arange(N), ranks]
    cand, level = kk // L, kk % L
    xi, ok = evaluate(problem, cand, level)
    if problem.constraints:
        xi = np.where(ok, xi, -np.inf)
    start_c = np.zeros(N, dtype=np.int64)
    start_l = np.zeros(N, dtype=np.int64)
    x0, ok0 = evaluate(problem, start_c, start_l)
    start = float(x0) if (ok0 or not problem.constraints) else -np.inf
    s = int(np.argmax(xi))
    if xi[s] > start:
        return float(xi[s]), cand[s], level[s]
    return start, start_c, start_l
