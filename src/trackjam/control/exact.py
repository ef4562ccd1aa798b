"""The proven optimum of Eqs. (12)-(13) by branch and bound (ours, beyond the paper), with a
time budget that returns the incumbent and a certified bound on its gap to the optimum.

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

The objective is written for S weighted target positions (sum_s w_s Xi at sample s; S = 1 is
Eq. (12) at x_bar). The bound of the pairs of an agent from rank r on takes, at every sample,
the largest p_D among them (a suffix maximum), which for S = 1 is p_D at rank r itself. With
the other agents fixed (the placed ones at their p_D, the others at their bounds), Xi at a
sample is A_s + B_s p_D of the agent being placed, so the bound of a pair costs S
multiply-adds once A and B are known for its depth.

The search is resumable: the compiled kernel runs a bounded number of nodes and returns to
Python, which keeps the clock (``time_limit_s``) and lets Ctrl-C through between chunks. When
the budget runs out, every unexplored branch is a run of siblings at some depth of the current
path; the largest of their bounds minus the incumbent's value is the certified gap.

``enumerate_optimum`` is the plain-numpy full enumeration the tests hold the kernel to.
"""

from __future__ import annotations

import abc
import dataclasses
import itertools
import time

import numpy as np
from numba import njit

from trackjam.control.objective import (
    evaluate,
    kernel_add_detector,
    kernel_at_least,
    kernel_feasible,
    mean_at_least,
    to_solution,
)
from trackjam.control.problem import Problem, Solution

#: wall time a chunk of the search aims at [s]: Ctrl-C and the clock are checked between chunks
CHUNK_S = 0.02


def pair_order(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Each agent's pairs k = c * L + l, ranked by (weighted mean) p_D descending, then level,
    then move.

    Returns ``order`` (N, C*L) padded with -1, and ``n_pairs`` (N,).
    """
    N, C, L = problem.p_d.shape
    p_s, w = problem.objective_tables()
    score = p_s[0] if w.shape[0] == 1 else np.tensordot(w, p_s, axes=1)
    order = np.full((N, C * L), -1, dtype=np.int64)
    n_pairs = problem.n_cand * L
    # every agent's real pairs in one sort, the agent as the first key: within an agent the
    # keys (p_D, level, move) order its pairs as a sort of its own would (no two pairs tie)
    i, k = np.nonzero(np.arange(C * L)[None, :] < n_pairs[:, None])
    c, l = np.divmod(k, L)
    rank = np.lexsort((c, l, -score[i, c, l], i))  # last key is primary
    start = np.concatenate(([0], np.cumsum(n_pairs)[:-1]))  # each agent's first index in the sort
    i = i[rank]
    order[i, np.arange(len(rank)) - start[i]] = k[rank]
    return order, n_pairs


_ONE = np.uint64(1)
_ZERO = np.uint64(0)
_ALL = ~np.uint64(0)
_DEBRUIJN = np.uint64(0x03F79D71B4CB0A89)
_CTZ = np.zeros(64, dtype=np.int64)
for _b in range(64):
    _CTZ[((1 << _b) * 0x03F79D71B4CB0A89 % (1 << 64)) >> 58] = _b


@njit(cache=True, inline="always")
def _ctz(m):
    """Index of the lowest set bit of a non-zero uint64."""
    low = m & (~m + _ONE)
    return _CTZ[np.int64((low * _DEBRUIJN) >> np.uint64(58))]


@njit(cache=True, inline="always")
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
def _pair_row(j, rj, rank_c, rank_l, n_pairs, gain, levels_w, delta, rows, have):
    """Bitsets ``rows[j, rj, k]`` (k > j): ranks of agent k compatible, pair by pair, with
    agent j at rank rj (neither puts delta or more on the other); built once, the first time
    they are needed (``have[j, rj]`` records it)."""
    if have[j, rj]:
        return
    have[j, rj] = True
    N = n_pairs.shape[0]
    cj = rank_c[j, rj]
    wj = levels_w[rank_l[j, rj]]
    for k in range(j + 1, N):
        for rk in range(n_pairs[k]):
            ck = rank_c[k, rk]
            if wj * gain[k, j, ck, cj] < delta and levels_w[rank_l[k, rk]] * gain[j, k, cj, ck] < delta:
                rows[j, rj, k, rk >> 6] |= _ONE << np.uint64(rk & 63)


@njit(cache=True, inline="always")
def _first_admissible(k, start, d, rank, rank_c, rank_l, n_pairs, rows, gain, levels_w, delta, c, lv, recv):
    """First rank >= ``start`` of agent k admissible against agents 0..d (n_pairs[k] if none).
    Inlined with the two helpers it calls: the search visited a node in 635 instead of 775 ns
    (N = 5, 79 controls, numba 0.68).

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


@njit(cache=True, inline="always")
def _place(d, gain, levels_w, c, lv, recv):
    """Agent d, now at (c[d], lv[d]), joins agents 0..d-1 in the received powers: recv[d, j] is
    what agent j receives from agents 0..d, recv[d, d] what agent d receives from 0..d-1."""
    inc = 0.0
    for j in range(d):
        inc += levels_w[lv[j]] * gain[d, j, c[d], c[j]]
        recv[d, j] = recv[d - 1, j] + levels_w[lv[d]] * gain[j, d, c[j], c[d]]
    recv[d, d] = inc


@njit(cache=True)
def kernel_mean_xi(pv, w, n, q):
    """sum_s w_s Xi^N_n(pv[s]) for ``pv`` (S, N); for S = 1, w = [1] it is Xi bit for bit."""
    acc = 0.0
    for s in range(w.shape[0]):
        acc += w[s] * kernel_at_least(pv[s], n, q)
    return acc


@njit(cache=True)
def kernel_ranked_tables(p_s, rank_c, rank_l, n_pairs):
    """``ps[s, i, r]``, p_D at sample s of agent i's pair of rank r (0 past its ``n_pairs[i]``
    real pairs), and ``smax``, its suffix maximum over r: compiled twin of
    :func:`ranked_tables_reference`, bit for bit (one pass instead of numpy's gather, mask and
    reversed accumulate: 0.36 instead of 0.57 ms over a belief of 48 samples)."""
    S, N, P = p_s.shape[0], p_s.shape[1], rank_c.shape[1]
    ps = np.empty((S, N, P))
    smax = np.empty((S, N, P))
    for s in range(S):
        for i in range(N):
            for r in range(P):
                ps[s, i, r] = p_s[s, i, rank_c[i, r], rank_l[i, r]] * (1.0 if r < n_pairs[i] else 0.0)
            acc = ps[s, i, P - 1]
            smax[s, i, P - 1] = acc
            for r in range(P - 2, -1, -1):
                x = ps[s, i, r]
                if not (acc >= x or acc != acc):  # np.maximum(acc, x): NaN or the larger, acc on ties
                    acc = x
                smax[s, i, r] = acc
    return ps, smax


def ranked_tables_reference(p_s, rank_c, rank_l, n_pairs) -> tuple[np.ndarray, np.ndarray]:
    """Plain-numpy twin of :func:`kernel_ranked_tables`."""
    N, P = rank_c.shape
    valid = np.arange(P)[None, :] < np.asarray(n_pairs)[:, None]
    ps = np.ascontiguousarray(p_s[:, np.arange(N)[:, None], rank_c, rank_l] * valid)
    return ps, np.ascontiguousarray(np.maximum.accumulate(ps[..., ::-1], axis=-1)[..., ::-1])


@njit(cache=True)
def kernel_start_value(p_s, w, gain, levels_w, delta, n, constrained, cand, level):
    """Objective of the starting incumbent (-inf when Eq. (13) is enforced and broken)."""
    S, N = p_s.shape[0], p_s.shape[1]
    pv = np.empty((S, N))
    for s in range(S):
        for i in range(N):
            pv[s, i] = p_s[s, i, cand[i], level[i]]
    if constrained and not kernel_feasible(gain, levels_w, delta, cand, level):
        return -np.inf
    return kernel_mean_xi(pv, w, n, np.empty(n + 1))


@njit(cache=True)
def _others_dp(d, n, p, smax, bptr, AB):
    """For every sample s: with agents 0..d-1 at ``p[s]`` and agents k > d at their bound
    ``smax[s, k, bptr[d, k]]``, AB[d, s] = (P(at least n of them detect), P(exactly n - 1 do)).

    Then agent d at p_D = x gives Xi = A + B x at sample s: the bound of any pair of agent d
    costs S multiply-adds instead of S dynamic programmes."""
    S, N = smax.shape[0], smax.shape[1]
    q = np.empty(n + 1)
    for s in range(S):
        q[0] = 1.0
        for m in range(1, n + 1):
            q[m] = 0.0
        for j in range(N):
            if j == d:
                continue
            kernel_add_detector(q, n, p[s, j] if j < d else smax[s, j, bptr[d, j]])
        AB[d, s, 0] = q[n]
        AB[d, s, 1] = q[n - 1]


@njit(cache=True)
def _linear_bound(d, r, table, w, AB):
    """sum_s w_s (A_s + B_s table[s, d, r]): the bound of agent d at p_D ``table[:, d, r]``."""
    acc = 0.0
    for s in range(w.shape[0]):
        acc += w[s] * (AB[d, s, 0] + AB[d, s, 1] * table[s, d, r])
    return acc


@njit(cache=True)
def kernel_branch_and_bound(w, gain, levels_w, delta, n, constrained, ps, smax, rank_c, rank_l,
                            n_pairs, rows, have, c, lv, rank, p, recv, bptr, cur, AB, best_cand,
                            best_level, state, best_value, max_nodes):
    """Maximise sum_s w_s Xi^N_n subject to Eq. (13) (when ``constrained``), resumably.

    ``ps[s, i, r]`` is p_D of agent i's pair of rank r at sample s, ``smax`` its suffix maximum
    over ranks; ``state`` = [depth, nodes visited], ``best_value`` = [incumbent value], and
    ``best_cand``/``best_level`` (N,) the incumbent; with ``c, lv, rank, p, recv, bptr, cur, AB``
    they are the whole search state, saved on return. Runs at most ``max_nodes`` more nodes
    (all of them when <= 0); returns True when the search is complete (the incumbent is then
    the optimum; -inf when nothing feasible exists).
    """
    S, N = ps.shape[0], ps.shape[1]
    pv = np.empty((S, N))
    q = np.empty(n + 1)
    d = state[0]
    nodes = state[1]
    best = best_value[0]
    stop = nodes + max_nodes
    if nodes == 0 and d == 0:
        _others_dp(0, n, p, smax, bptr, AB)
    while d >= 0:
        descended = False
        while cur[d] < n_pairs[d]:
            if max_nodes > 0 and nodes >= stop:
                state[0] = d
                state[1] = nodes
                best_value[0] = best
                return False
            r = cur[d]
            if constrained and d > 0:
                r = _first_admissible(d, r, d - 1, rank, rank_c, rank_l, n_pairs, rows, gain,
                                      levels_w, delta, c, lv, recv)
                if r == n_pairs[d]:
                    cur[d] = r
                    break
            cur[d] = r + 1
            nodes += 1
            if _linear_bound(d, r, smax, w, AB) <= best:
                cur[d] = n_pairs[d]  # no later pair of agent d does better
                break
            if S > 1 and _linear_bound(d, r, ps, w, AB) <= best:
                continue
            c[d] = rank_c[d, r]
            lv[d] = rank_l[d, r]
            rank[d] = r
            for s in range(S):
                p[s, d] = ps[s, d, r]
            if constrained:
                _place(d, gain, levels_w, c, lv, recv)
            if d == N - 1:
                value = kernel_mean_xi(p, w, n, q)
                if value > best:
                    best = value
                    best_cand[:] = c
                    best_level[:] = lv
                if S == 1:
                    cur[d] = n_pairs[d]  # later pairs have lower or equal p_D
                    break
                continue
            if constrained and not have[d, r]:
                _pair_row(d, r, rank_c, rank_l, n_pairs, gain, levels_w, delta, rows, have)
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
            if dead:
                continue
            for s in range(S):
                for j in range(d + 1):
                    pv[s, j] = p[s, j]
                for k in range(d + 1, N):
                    pv[s, k] = smax[s, k, bptr[d + 1, k]]
            if kernel_mean_xi(pv, w, n, q) <= best:
                continue
            d += 1
            cur[d] = bptr[d, d]
            _others_dp(d, n, p, smax, bptr, AB)
            descended = True
            break
        if not descended:
            d -= 1
    state[0] = d
    state[1] = nodes
    best_value[0] = best
    return True


class ChunkedSearch(abc.ABC):
    """A branch and bound run in chunks under a time or node budget (the module docstring). A
    subclass builds its state (with :meth:`_init_placement`), runs its kernel for at most
    ``max_nodes`` more nodes in ``_advance`` and bounds the branches left in ``open_bound``."""

    def _init_placement(self, n_agents: int, n_ranks: int, constrained: bool, start: float) -> None:
        """The state every search keeps while it places agents: the pairwise-compatibility
        bitsets of forward checking (built lazily), the placed agents' candidates, levels and
        ranks, the powers they receive, each depth's next rank, and the incumbent's value."""
        N, P = n_agents, n_ranks
        W = (P + 63) // 64 if constrained else 1
        self.rows = np.zeros((N if constrained else 1, P if constrained else 1, N, W), dtype=np.uint64)
        self.have = np.zeros((N, P), dtype=np.bool_)
        self.c = np.zeros(N, dtype=np.int64)
        self.lv = np.zeros(N, dtype=np.int64)
        self.rank = np.zeros(N, dtype=np.int64)
        self.recv = np.zeros((N, N))  # recv[d, j]: power at agent j from agents 0..d
        self.cur = np.zeros(N, dtype=np.int64)
        self.state = np.zeros(2, dtype=np.int64)  # [depth, nodes visited]
        self.best_value = np.array([start])
        self.finished = False

    @abc.abstractmethod
    def _advance(self, max_nodes: int) -> bool:
        """Run the kernel for at most ``max_nodes`` more nodes (all when <= 0); True when done."""

    @abc.abstractmethod
    def open_bound(self) -> float:
        """Largest bound of any branch not yet explored (-inf when none is left)."""

    @property
    def nodes(self) -> int:
        return int(self.state[1])

    @property
    def value(self) -> float:
        """Value of the incumbent."""
        return float(self.best_value[0])

    def step(self, max_nodes: int) -> bool:
        """Run at most ``max_nodes`` more nodes (all when <= 0); True when the search is done."""
        if not self.finished:
            self.finished = bool(self._advance(int(max_nodes)))
        return self.finished

    def run(self, time_limit_s: float | None = None, node_limit: int = 0) -> bool:
        """Search until done, ``time_limit_s`` [s] has passed or ``node_limit`` nodes (> 0) have
        been visited; returns whether the search is complete."""
        start = time.perf_counter()
        chunk = 2048
        while True:
            if node_limit > 0:
                chunk = min(chunk, node_limit - self.nodes)
                if chunk <= 0:
                    return self.finished
            t0 = time.perf_counter()
            if self.step(chunk):
                return True
            now = time.perf_counter()
            if time_limit_s is not None:
                left = time_limit_s - (now - start)
                if left <= 0:
                    return False
                aim = min(CHUNK_S, left)
            else:
                aim = CHUNK_S
            # keep each chunk near ``aim`` seconds, whatever a node costs on this instance
            rate = chunk / max(now - t0, 1e-6)
            chunk = int(min(max(rate * aim, 64), 1 << 26))

    def _certified(self, sol):
        """``sol`` (the incumbent) with whether it is proven optimal and the certified gap: the
        largest open bound minus its value (0 when proven)."""
        gap = max(self.open_bound() - self.value, 0.0)
        return dataclasses.replace(sol, optimal=gap == 0.0, gap=gap, nodes=self.nodes)


class BranchAndBound(ChunkedSearch):
    """One exact search over a :class:`Problem`, run in chunks (see the module docstring)."""

    def __init__(self, problem: Problem):
        self.problem = problem
        N, C, L = problem.p_d.shape
        p_s, self.w = problem.objective_tables()
        order, self.n_pairs = pair_order(problem)
        P = order.shape[1]
        valid = order >= 0
        self.rank_c = np.where(valid, order // L, 0)
        self.rank_l = np.where(valid, order % L, 0)
        self.ps, self.smax = kernel_ranked_tables(np.ascontiguousarray(p_s), self.rank_c, self.rank_l, self.n_pairs)
        self.p = np.zeros((p_s.shape[0], N))
        self.bptr = np.zeros((N + 1, N), dtype=np.int64)  # first admissible rank of k given 0..d-1
        self.AB = np.zeros((N, p_s.shape[0], 2))  # per depth and sample: Xi = A + B p_D (see _others_dp)
        self.best_cand = np.zeros(N, dtype=np.int64)
        self.best_level = np.zeros(N, dtype=np.int64)
        start = kernel_start_value(p_s, self.w, problem.gain, problem.levels_w, problem.delta_w,
                                   problem.at_least, problem.constraints, self.best_cand, self.best_level)
        self._init_placement(N, P, problem.constraints, start)

    def _advance(self, max_nodes: int) -> bool:
        P = self.problem
        return kernel_branch_and_bound(
            self.w, P.gain, P.levels_w, P.delta_w, P.at_least, P.constraints, self.ps, self.smax,
            self.rank_c, self.rank_l, self.n_pairs, self.rows, self.have, self.c, self.lv, self.rank,
            self.p, self.recv, self.bptr, self.cur, self.AB, self.best_cand, self.best_level, self.state,
            self.best_value, max_nodes,
        )

    def open_bound(self) -> float:
        """Largest bound of any branch not yet explored (-inf when none is left)."""
        if self.finished:
            return -np.inf
        N, n = self.problem.n_agents, self.problem.at_least
        out = -np.inf
        for e in range(int(self.state[0]) + 1):
            r = self.cur[e]
            if r >= self.n_pairs[e]:
                continue
            pv = np.empty((self.ps.shape[0], N))
            pv[:, :e] = self.p[:, :e]
            pv[:, e] = self.smax[:, e, r]
            for k in range(e + 1, N):
                pv[:, k] = self.smax[:, k, self.bptr[e, k]]
            out = max(out, float(mean_at_least(pv, self.w, n)))
        return out

    def solution(self) -> Solution:
        """The incumbent as a :class:`Solution`, with whether it is proven optimal and the
        certified gap: the largest open bound minus its value (0 when proven)."""
        return self._certified(to_solution(self.problem, self.best_cand, self.best_level))


def solve_exact(problem: Problem, time_limit_s: float | None = None, node_limit: int = 0) -> Solution:
    """The optimum of Eqs. (12)-(13) (of Eq. 12 alone when constraints are off), or, when
    ``time_limit_s`` [s] or ``node_limit`` nodes run out first, the best plan found with its
    certified gap (``Solution.optimal``, ``Solution.gap``)."""
    search = BranchAndBound(problem)
    search.run(time_limit_s, node_limit)
    return search.solution()


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
