"""The proven optimum of the K-target decision (:mod:`assignment_problem`) by branch and bound
(ours), with the one-target solver's time budget and certified gap.

With K = 1 agents are placed in index order; with K > 1 the agents that can matter most come
first: greedily, the one whose best p_D adds most to the targets' chance of being seen by some
placed agent (:func:`agent_order`). On the benchmark's K = 2, N = 4 instances, sorting by best
p_D alone searched 35 times fewer nodes in total than index order (60 instances), and this
order halved the total again (200 instances per objective), mostly on the hardest ones.
Each agent's choices form K blocks, one per target, in target order; within block k its
(candidate, level) pairs come in the one-target order (p_D at x_bar_k descending, then lower
level, then lower move: :func:`pair_order`). The result is the first optimum in this order
(improvements must be strict; the start is every agent hovering at level 0 serving target 0);
with K = 1 the order is the one-target search's, so it returns its plan. Before the search,
:mod:`assignment_incumbent` builds a feasible plan of value v, and the search starts with that
plan as its incumbent at the value v - 1e-9 max(1, |v|): it prunes whatever cannot beat v from
the first node on, while the first optimum in the order, worth at least v, is still reached and
taken. A complete search therefore returns the same plan as from the start alone; one stopped
by its budget may return the constructed plan. Eq. (13) is forward-checked as there, with the
one-target kernels over extended candidates (slot c aimed at x_bar_k).

The bound. At depth d (d agents placed) every unplaced agent j has, per target k, its
best p_D b_jk among pairs still admissible against the placed agents (none: it cannot serve k).
If a completion sends a_k unplaced agents to target k, Xi_k is at most U_k(a_k): Xi of the
placed servers of k and the a_k largest b_jk, with threshold min(n, m_k + a_k) (Xi rises with
every p_D when the threshold is fixed, and the a_k largest dominate any a_k of them). The bound
is the best team objective over counts (a_1..a_K) summing to the number of unplaced agents, a
small dynamic programme over targets. For agent d itself serving k with p_D = x, U_k is
A + B x (A = P(at least t others detect), B = P(exactly t - 1 do)), so the bound rises with x:
once a pair of block k is cut, the rest of block k is too.

That bound lets an unplaced agent count for every target at once. For ``sum`` with n = 1, where
Xi_k = 1 - M_k prod(1 - p) is a coverage (M_k the placed servers' miss product), the union bound
1 - M prod(1 - p_i) <= 1 - M + M sum_i p_i counts each agent once: the objective is at most
sum_k (1 - M_k) + M_k x + sum_{j unplaced} max_k M_k b_jk, which also rises with x, and the
search uses the smaller of the two (plus 1e-12 against rounding). On swarm-3 with n = 1 the
hardest steps (K = 4 aims, N = 5) had a gap of 0.95 between the first bound and the optimum.

The tests hold the kernel to a plain-numpy enumeration of every choice in this order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from trackjam.control.assignment_incumbent import kernel_incumbent
from trackjam.control.assignment_problem import (
    AssignmentProblem,
    AssignmentSolution,
    kernel_targets_value,
    to_assignment_solution,
)
from trackjam.control.exact import (
    ChunkedSearch,
    _first_admissible,
    _pair_row,
    _place,
    pair_order,
)
from trackjam.control.objective import kernel_add_detector, kernel_feasible


COVER_SLACK = 1e-12  # added to the coverage bound: its products are rounded unlike the objective's recursion


@njit(cache=True)
def _comb(kind, a, b):
    """The team objective of two partial values: sum or min (-inf absorbs)."""
    if a == -np.inf or b == -np.inf:
        return -np.inf
    return a + b if kind == 0 else min(a, b)


@njit(cache=True)
def _tail(q, n, t):
    """P(at least t detect) from the truncated count law ``q`` (q[n] = P(at least n))."""
    acc = q[n]
    for m in range(t, n):
        acc += q[m]
    return acc


@njit(cache=True)
def _tables(d, n, kind, ps, blk, tg, pp, bptr, A, B, R, H):
    """The bound's tables of depth d: for every target k and count a of unplaced agents sent to
    it, ``A[d, k, a] + B[d, k, a] x`` bounds Xi_k with agent d at p_D x also serving k, and
    ``R[d, k, r]`` is the best combination of the other targets' U with r unplaced agents. For
    ``sum`` with n = 1, ``H[d, k]`` is the placed agents' miss product on target k and ``H[d,
    K]`` the coverage bound without agent d (the module docstring)."""
    N, K = bptr.shape[1], bptr.shape[2]
    u = N - 1 - d
    q = np.empty(n + 1)
    b = np.empty(N)
    W = np.full((K, N), -np.inf)  # U_k(a) without agent d
    if kind == 0 and n == 1:
        H[d, :K] = 1.0
        for j in range(d):
            H[d, tg[j]] *= 1.0 - pp[j]
        cover = 0.0
        for k in range(K):
            cover += 1.0 - H[d, k]
        for j in range(d + 1, N):
            gain = 0.0
            for k in range(K):
                r = bptr[d, j, k]
                if r < (k + 1) * blk[j]:
                    gain = max(gain, H[d, k] * ps[j, r])
            cover += gain
        H[d, K] = cover
    for k in range(K):
        q[0] = 1.0
        q[1:] = 0.0
        m = 0
        for j in range(d):
            if tg[j] == k:
                kernel_add_detector(q, n, pp[j])
                m += 1
        nb = 0
        for j in range(d + 1, N):
            r = bptr[d, j, k]
            if r < (k + 1) * blk[j]:
                x = ps[j, r]
                pos = nb  # insertion sort, descending
                while pos > 0 and b[pos - 1] < x:
                    b[pos] = b[pos - 1]
                    pos -= 1
                b[pos] = x
                nb += 1
        for a in range(u + 1):
            if a > nb:
                A[d, k, a] = -np.inf
                B[d, k, a] = 0.0
                continue
            if a > 0:
                kernel_add_detector(q, n, b[a - 1])
            W[k, a] = 0.0 if m + a == 0 else _tail(q, n, min(n, m + a))
            t = min(n, m + a + 1)
            A[d, k, a] = _tail(q, n, t)
            B[d, k, a] = q[t - 1]
    best = np.empty(u + 1)
    new = np.empty(u + 1)
    for k in range(K):
        best[:] = -np.inf
        best[0] = 0.0 if kind == 0 else np.inf
        for k2 in range(K):
            if k2 == k:
                continue
            for r in range(u + 1):
                v = -np.inf
                for a in range(r + 1):
                    v = max(v, _comb(kind, best[r - a], W[k2, a]))
                new[r] = v
            best[:] = new
        R[d, k, : u + 1] = best


@njit(cache=True)
def kernel_pair_bound(d, k, x, kind, n, A, B, R, H, n_agents):
    """Bound of every completion with agent d serving target k at p_D ``x``."""
    u = n_agents - 1 - d
    out = -np.inf
    for a in range(u + 1):
        if A[d, k, a] == -np.inf:
            break  # fewer than a agents can serve k
        out = max(out, _comb(kind, A[d, k, a] + B[d, k, a] * x, R[d, k, u - a]))
    if kind == 0 and n == 1:
        K = H.shape[1] - 1
        out = min(out, H[d, K] + H[d, k] * x + COVER_SLACK)
    return out


@njit(cache=True)
def kernel_assignment_bb(pz, gain, levels_w, delta, n, kind, constrained, agent, ps, rank_c, rank_l,
                         rank_pair, blk, n_pairs, rows, have, c, lv, rank, tg, pp, pair, recv, bptr, cur,
                         A, B, R, H, best_pair, best_target, state, best_value, max_nodes):
    """Maximise the team objective subject to Eq. (13) (when ``constrained``), resumably.

    Depth d places agent ``agent[d]``: ``gain`` and the rank tables are in placing order, ``pz``
    and the incumbent ``best_pair``/``best_target`` in agent order (a plan's value is computed
    in agent order, as :func:`assignment_value` does). ``ps[d, r]`` is p_D of the choice of rank
    r (block r // blk[d] is its target), ``rank_c``/``rank_l`` its extended candidate and level,
    ``rank_pair`` its pair c * L + l;
    ``state`` = [depth, nodes], ``best_value`` = [incumbent]; with the other arrays they are the
    whole search state. Runs at most ``max_nodes`` more nodes (all when <= 0); True when done.
    """
    N = n_pairs.shape[0]
    kk = np.empty(N, dtype=np.int64)
    op = np.empty(N, dtype=np.int64)
    ot = np.empty(N, dtype=np.int64)
    pw = np.empty(N)
    q = np.empty(n + 1)
    d = state[0]
    nodes = state[1]
    best = best_value[0]
    stop = nodes + max_nodes
    if nodes == 0 and d == 0:
        _tables(0, n, kind, ps, blk, tg, pp, bptr, A, B, R, H)
    while d >= 0:
        descended = False
        while cur[d] < n_pairs[d]:
            if max_nodes > 0 and nodes >= stop:
                state[0] = d
                state[1] = nodes
                best_value[0] = best
                return False
            k = cur[d] // blk[d]
            end = (k + 1) * blk[d]
            r = max(cur[d], bptr[d, d, k])
            if constrained and d > 0 and r < end:
                r = _first_admissible(d, r, d - 1, rank, rank_c, rank_l, n_pairs, rows, gain,
                                      levels_w, delta, c, lv, recv)
            if r >= end:
                cur[d] = end
                continue
            cur[d] = r + 1
            nodes += 1
            if kernel_pair_bound(d, k, ps[d, r], kind, n, A, B, R, H, N) <= best:
                cur[d] = end  # no later pair of this block does better
                continue
            c[d] = rank_c[d, r]
            lv[d] = rank_l[d, r]
            rank[d] = r
            tg[d] = k
            pp[d] = ps[d, r]
            pair[d] = rank_pair[d, r]
            if constrained:
                _place(d, gain, levels_w, c, lv, recv)
            if d == N - 1:
                for j in range(N):
                    op[agent[j]] = pair[j]
                    ot[agent[j]] = tg[j]
                value = kernel_targets_value(pz, n, kind, op, ot, kk, pw, q)
                if value > best:
                    best = value
                    best_pair[:] = op
                    best_target[:] = ot
                cur[d] = end  # later pairs of the block have lower or equal p_D
                continue
            if constrained and not have[d, r]:
                _pair_row(d, r, rank_c, rank_l, n_pairs, gain, levels_w, delta, rows, have)
            dead = False
            for j in range(d + 1, N):
                alive = False
                for k2 in range(bptr.shape[2]):
                    e2 = (k2 + 1) * blk[j]
                    rr = bptr[d, j, k2]
                    if constrained and rr < e2:
                        rr = min(_first_admissible(j, rr, d, rank, rank_c, rank_l, n_pairs, rows, gain,
                                                   levels_w, delta, c, lv, recv), e2)
                    bptr[d + 1, j, k2] = rr
                    alive = alive or rr < e2
                if not alive:
                    dead = True
                    break
            if dead:
                continue
            d += 1
            cur[d] = 0
            _tables(d, n, kind, ps, blk, tg, pp, bptr, A, B, R, H)
            descended = True
            break
        if not descended:
            d -= 1
    state[0] = d
    state[1] = nodes
    best_value[0] = best
    return True


@njit(cache=True)
def kernel_start(pz, gain, levels_w, delta, n, kind, constrained, n_agents):
    """Value of the starting incumbent: every agent hovering at level 0 serving target 0
    (-inf when Eq. (13) is enforced and broken)."""
    z = np.zeros(n_agents, dtype=np.int64)
    if constrained and not kernel_feasible(gain, levels_w, delta, z, z):
        return -np.inf
    return kernel_targets_value(pz, n, kind, z, z, np.empty(n_agents, dtype=np.int64),
                                np.empty(n_agents), np.empty(n + 1))


def agent_order(problem: AssignmentProblem) -> np.ndarray:
    """The order the search places the agents in: index order for one target; else, greedily,
    the agent adding most to sum_k P(some placed agent detects k), each agent at its best p_D
    b_ik per target (score max_k b_ik prod_placed (1 - b_jk); ties to the lower index)."""
    N = problem.n_agents
    if problem.n_targets == 1:
        return np.arange(N)
    best = problem.pz.max(axis=2).T  # (N, K)
    miss = np.ones(problem.n_targets)
    left = list(range(N))
    order = []
    while left:
        i = left[int(np.argmax([(best[j] * miss).max() for j in left]))]
        order.append(i)
        left.remove(i)
        miss = miss * (1.0 - best[i])
    return np.array(order, dtype=np.int64)


INCUMBENT_MARGIN = 1e-9  # the constructed plan's value is lowered by this (relative) before the search


class AssignmentSearch(ChunkedSearch):
    """One exact search over an :class:`AssignmentProblem`, run in chunks; ``incumbent=False``
    starts it from every agent hovering at level 0 alone (the module docstring)."""

    def __init__(self, problem: AssignmentProblem, incumbent: bool = True):
        self.problem = problem
        N, K, C, L = problem.n_agents, problem.n_targets, problem.n_slots, problem.n_levels
        self.agent = agent_order(problem)
        self.gain = np.ascontiguousarray(problem.gain[np.ix_(self.agent, self.agent)])
        self.blk = problem.n_cand[self.agent] * L
        self.n_pairs = K * self.blk
        P = int(self.n_pairs.max())
        self.rank_c = np.zeros((N, P), dtype=np.int64)
        self.rank_l = np.zeros((N, P), dtype=np.int64)
        self.rank_pair = np.zeros((N, P), dtype=np.int64)
        self.ps = np.zeros((N, P))
        for k, Pk in enumerate(problem.targets):
            order, _ = pair_order(Pk)
            for d, i in enumerate(self.agent):
                b = int(self.blk[d])
                o = order[i, :b]
                self.rank_c[d, k * b:(k + 1) * b] = k * C + o // L
                self.rank_l[d, k * b:(k + 1) * b] = o % L
                self.rank_pair[d, k * b:(k + 1) * b] = o
                self.ps[d, k * b:(k + 1) * b] = problem.pz[k, i, o]
        constrained = problem.constraints
        self.tg = np.zeros(N, dtype=np.int64)
        self.pp = np.zeros(N)
        self.pair = np.zeros(N, dtype=np.int64)
        self.bptr = np.zeros((N + 1, N, K), dtype=np.int64)
        self.bptr[0] = np.arange(K)[None, :] * self.blk[:, None]
        self.A = np.zeros((N, K, N))
        self.B = np.zeros((N, K, N))
        self.R = np.zeros((N, K, N))
        self.H = np.zeros((N, K + 1))
        self.best_pair = np.zeros(N, dtype=np.int64)
        self.best_target = np.zeros(N, dtype=np.int64)
        start = kernel_start(problem.pz, problem.gain, problem.levels_w, problem.delta_w, problem.at_least,
                             problem.kind, constrained, N)
        self._init_placement(N, P, constrained, start)
        if incumbent:
            pair, target = np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.int64)
            v = kernel_incumbent(problem.pz, problem.gain, problem.levels_w, problem.delta_w, problem.at_least,
                                 problem.kind, constrained, problem.n_cand, self.agent, pair, target)
            bound = v - INCUMBENT_MARGIN * max(1.0, abs(v))
            if np.isfinite(v) and bound > start:
                self.best_value[0] = bound
                self.best_pair[:] = pair
                self.best_target[:] = target

    def _advance(self, max_nodes: int) -> bool:
        P = self.problem
        return kernel_assignment_bb(
            P.pz, self.gain, P.levels_w, P.delta_w, P.at_least, P.kind, P.constraints, self.agent, self.ps,
            self.rank_c, self.rank_l, self.rank_pair, self.blk, self.n_pairs, self.rows, self.have,
            self.c, self.lv, self.rank, self.tg, self.pp, self.pair, self.recv, self.bptr, self.cur,
            self.A, self.B, self.R, self.H, self.best_pair, self.best_target, self.state, self.best_value,
            max_nodes,
        )

    def open_bound(self) -> float:
        """Largest bound of any branch not yet explored (-inf when none is left): at every depth
        of the current path, each target block's next untried pair."""
        if self.finished:
            return -np.inf
        N = self.problem.n_agents
        out = -np.inf
        for e in range(int(self.state[0]) + 1):
            r = int(self.cur[e])
            while r < self.n_pairs[e]:
                k = r // int(self.blk[e])
                end = (k + 1) * int(self.blk[e])
                r = max(r, int(self.bptr[e, e, k]))
                if r < end:
                    out = max(out, float(kernel_pair_bound(e, k, self.ps[e, r], self.problem.kind,
                                                           self.problem.at_least, self.A, self.B, self.R,
                                                           self.H, N)))
                r = end
        return out

    def solution(self) -> AssignmentSolution:
        """The incumbent, with whether it is proven optimal and its certified gap."""
        L = self.problem.n_levels
        return self._certified(to_assignment_solution(self.problem, self.best_pair // L, self.best_pair % L,
                                                      self.best_target))


def solve_assignment_exact(problem: AssignmentProblem, time_limit_s: float | None = None,
                           node_limit: int = 0) -> AssignmentSolution:
    """The optimum of the K-target decision, or, when ``time_limit_s`` [s] or ``node_limit``
    nodes run out first, the best plan found with its certified gap."""
    search = AssignmentSearch(problem)
    search.run(time_limit_s, node_limit)
    return search.solution()
