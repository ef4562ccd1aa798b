"""The paper's distributed GRASP (Section V-D, :mod:`grasp`) extended to the choice of target
(ours, issue 12).

Each agent j, with its own random stream, runs n_I iterations of

1. n_s joint controls, each agent's (candidate, level, target) drawn uniformly from its
   n_cand * L * K choices (index kk -> target kk // (n_cand L), pair kk mod (n_cand L) as in
   the one-target GRASP); the best feasible one is kept (first in sample order among ties);
2. a local search of agent j alone over {u-, u, u+} x {l-, l, l+} x {every target}, the others
   fixed (u-, u+, l-, l+ and their draws as in the one-target GRASP; targets in index order,
   after the move and the level); a neighbour replaces the incumbent only when strictly better;

and the team applies the best of the agents' results (ties to the lower agent). Every agent
hovering at level 0 and serving target 0 starts every search. With K = 1 the draws, values and
ties are the one-target GRASP's, so the plan is the same.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit

from trackjam.control.assignment_problem import (
    AssignmentProblem,
    AssignmentSolution,
    assignment_value,
    kernel_targets_value,
    to_assignment_solution,
)
from trackjam.control.grasp import neighbour_lists


@njit(cache=True, nogil=True)
def _feasible(gain, levels_w, delta, C, pair, target, L):
    """Eq. (13) over extended candidates (slot c aimed at target k is k * C + c)."""
    N = pair.shape[0]
    for i in range(N):
        vi = target[i] * C + pair[i] // L
        r = 0.0
        for j in range(N):
            if j != i:
                r += levels_w[pair[j] % L] * gain[i, j, vi, target[j] * C + pair[j] // L]
        if r >= delta:
            return False
    return True


@njit(cache=True, nogil=True)
def _value(pz, gain, levels_w, delta, n, kind, constrained, C, pair, target, kk, p, q):
    """The team objective of a joint choice, or -inf when Eq. (13) is enforced and broken."""
    L = levels_w.shape[0]
    if constrained and not _feasible(gain, levels_w, delta, C, pair, target, L):
        return -np.inf
    return kernel_targets_value(pz, n, kind, pair, target, kk, p, q)


@njit(cache=True, nogil=True)
def kernel_assignment_grasp(rng, me, pz, gain, levels_w, delta, n, kind, constrained, n_cand, neigh,
                            n_neigh, samples, iterations, best_pair, best_target):
    """Agent ``me``'s search; writes its best choice into ``best_pair`` (c * L + l) and
    ``best_target`` (both (N,), on entry the starting incumbent) and returns its value."""
    N = n_cand.shape[0]
    K = pz.shape[0]
    L = levels_w.shape[0]
    C = gain.shape[2] // K
    kk = np.empty(N, dtype=np.int64)
    p = np.empty(N)
    q = np.empty(n + 1)
    pr = np.empty(N, dtype=np.int64)
    tg = np.empty(N, dtype=np.int64)
    it_p = np.empty(N, dtype=np.int64)
    it_t = np.empty(N, dtype=np.int64)
    blk = n_cand * L
    M = blk * K
    start_p = best_pair.copy()
    start_t = best_target.copy()
    best = _value(pz, gain, levels_w, delta, n, kind, constrained, C, best_pair, best_target, kk, p, q)
    start = best
    for _ in range(iterations):
        it_best = -np.inf
        for _s in range(samples):
            for i in range(N):
                pr[i] = min(int(rng.random() * M[i]), M[i] - 1)
                tg[i] = 0
                while pr[i] >= blk[i]:  # pr // blk without a division: K is small
                    pr[i] -= blk[i]
                    tg[i] += 1
            xi = kernel_targets_value(pz, n, kind, pr, tg, kk, p, q)
            if xi > it_best and (not constrained or _feasible(gain, levels_w, delta, C, pr, tg, L)):
                it_best = xi
                it_p[:] = pr
                it_t[:] = tg
        if it_best == -np.inf:
            it_best = start
            it_p[:] = start_p
            it_t[:] = start_t
        u = it_p[me] // L
        m = n_neigh[me, u]
        if m >= 2:
            a = min(int(rng.random() * m), m - 1)
            b = min(int(rng.random() * (m - 1)), m - 2)
            if b >= a:
                b += 1
            u_minus, u_plus = neigh[me, u, a], neigh[me, u, b]
        elif m == 1:
            u_minus, u_plus = neigh[me, u, 0], neigh[me, u, 0]
        else:
            u_minus, u_plus = u, u
        l0 = it_p[me] % L
        l_minus, l_plus = max(l0 - 1, 0), min(l0 + 1, L - 1)
        pr[:] = it_p
        tg[:] = it_t
        ls_best = it_best
        ls_p, ls_t = it_p[me], it_t[me]
        for uu in (u_minus, u, u_plus):
            for ll in (l_minus, l0, l_plus):
                for k in range(K):
                    pr[me] = uu * L + ll
                    tg[me] = k
                    v = _value(pz, gain, levels_w, delta, n, kind, constrained, C, pr, tg, kk, p, q)
                    if v > ls_best:
                        ls_best = v
                        ls_p, ls_t = uu * L + ll, k
        if ls_best > best:
            best = ls_best
            best_pair[:] = it_p
            best_target[:] = it_t
            best_pair[me] = ls_p
            best_target[me] = ls_t
    return best


def assignment_grasp_reference(rng, me, problem: AssignmentProblem, neigh, n_neigh, samples, iterations):
    """Plain-numpy twin of :func:`kernel_assignment_grasp` from the starting incumbent (same
    draws, same ties); returns (value, pairs c * L + l, targets)."""
    N, K, L = problem.n_agents, problem.n_targets, problem.n_levels

    def values(pair, target):
        v, ok = assignment_value(problem, pair // L, pair % L, target)
        return np.where(ok, v, -np.inf) if problem.constraints else v

    start_p = np.zeros(N, dtype=np.int64)
    start_t = np.zeros(N, dtype=np.int64)
    best_p, best_t = start_p.copy(), start_t.copy()
    start = best = float(values(start_p, start_t))
    blk = problem.n_cand * L
    M = blk * K
    for _ in range(iterations):
        U = rng.random((samples, N))
        x = np.minimum((U * M).astype(np.int64), M - 1)
        tg, pr = x // blk, x % blk
        v = values(pr, tg)
        s = int(np.argmax(v))
        if v[s] == -np.inf:
            it_best, it_p, it_t = start, start_p.copy(), start_t.copy()
        else:
            it_best, it_p, it_t = float(v[s]), pr[s].copy(), tg[s].copy()
        u = it_p[me] // L
        m = n_neigh[me, u]
        if m >= 2:
            a = min(int(rng.random() * m), m - 1)
            b = min(int(rng.random() * (m - 1)), m - 2)
            b += b >= a
            us = [neigh[me, u, a], u, neigh[me, u, b]]
        else:
            us = [neigh[me, u, 0] if m == 1 else u, u, neigh[me, u, 0] if m == 1 else u]
        l0 = it_p[me] % L
        ls = [max(l0 - 1, 0), l0, min(l0 + 1, L - 1)]
        trials = [(uu * L + ll, k) for uu in us for ll in ls for k in range(K)]
        trial_p = np.tile(it_p, (len(trials), 1))
        trial_t = np.tile(it_t, (len(trials), 1))
        trial_p[:, me] = [t[0] for t in trials]
        trial_t[:, me] = [t[1] for t in trials]
        tv = values(trial_p, trial_t)
        t = int(np.argmax(tv))
        if tv[t] > it_best:
            it_best, it_p, it_t = float(tv[t]), trial_p[t], trial_t[t]
        if it_best > best:
            best, best_p, best_t = it_best, it_p.copy(), it_t.copy()
    return best, best_p, best_t


def solve_assignment_grasp(problem: AssignmentProblem, rngs: list[np.random.Generator], samples: int = 10000,
                           iterations: int = 100, neighbours: int = 6, threads: int = 1) -> AssignmentSolution:
    """Every agent runs its search with ``rngs[j]``; all apply the best (ties: lower j);
    ``threads > 1`` runs the searches side by side (same result)."""
    N, L = problem.n_agents, problem.n_levels
    if len(rngs) < N:
        raise ValueError(f"grasp needs one random generator per agent ({N}), got {len(rngs)}")
    neigh, n_neigh = neighbour_lists(problem.targets[0], neighbours)
    values = np.empty(N)
    pairs = np.zeros((N, N), dtype=np.int64)
    targets = np.zeros((N, N), dtype=np.int64)

    def search(j: int) -> None:
        values[j] = kernel_assignment_grasp(
            rngs[j], j, problem.pz, problem.gain, problem.levels_w, problem.delta_w, problem.at_least,
            problem.kind, problem.constraints, problem.n_cand, neigh, n_neigh, int(samples), int(iterations),
            pairs[j], targets[j],
        )

    if threads > 1 and N > 1:
        with ThreadPoolExecutor(max_workers=min(threads, N)) as pool:
            list(pool.map(search, range(N)))
    else:
        for j in range(N):
            search(j)
    best = int(np.argmax(values))
    return to_assignment_solution(problem, pairs[best] // L, pairs[best] % L, targets[best])
