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

import numpy as np
from numba import njit

from trackjam.control.assignment_problem import (
    AssignmentProblem,
    AssignmentSolution,
    assignment_value,
    kernel_targets_value,
    kernel_targets_value_unrolled,
    to_assignment_solution,
)
from trackjam.control.grasp import (
    GRASP_CHUNK_SAMPLES,
    GraspState,
    _chunk_end,
    _pause,
    _resumed,
    grasp_reference_loop,
    kernel_local_neighbourhood,
    local_neighbourhood_reference,
    neighbour_lists,
    run_in_chunks,
    search_every_agent,
)


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


@njit(cache=True, nogil=True, inline="always")
def _draw_choice(rng, M, blk, pr, tg):
    """One joint sample (step 1 of the module docstring): agent i's pair ``pr[i]`` and target
    ``tg[i]`` from one uniform index among its M[i] = blk[i] K choices."""
    for i in range(M.shape[0]):
        pr[i] = min(int(rng.random() * M[i]), M[i] - 1)
        tg[i] = 0
        while pr[i] >= blk[i]:  # pr // blk without a division: K is small
            pr[i] -= blk[i]
            tg[i] += 1


@njit(cache=True, nogil=True)
def kernel_assignment_resume(rng, me, pz, gain, levels_w, delta, n, kind, constrained, n_cand, neigh, n_neigh,
                             samples, iterations, best_pair, best_target, start_p, start_t, it_p, it_t,
                             fstate, istate, budget):
    """Agent ``me``'s search, resumable as :func:`~trackjam.control.grasp.kernel_grasp_resume`:
    it draws at most ``budget`` more joint samples and returns True when the search has ended.
    State: the best choice so far in ``best_pair`` (c * L + l) and ``best_target`` ((N,), on the
    first call the starting incumbent, also in ``start_p``/``start_t``), the iteration's best
    sample in ``it_p``/``it_t``, ``fstate`` = [start value, best value, the iteration's best]
    and ``istate`` = [iteration, sample] (0 on the first call)."""
    N = n_cand.shape[0]
    K = pz.shape[0]
    L = levels_w.shape[0]
    C = gain.shape[2] // K
    kk = np.empty(N, dtype=np.int64)
    p = np.empty(N)
    q = np.empty(n + 1)
    pr = np.empty(N, dtype=np.int64)
    tg = np.empty(N, dtype=np.int64)
    blk = n_cand * L
    M = blk * K
    start, best, it_best, it, first = _resumed(fstate, istate)
    used = 0
    state_p, state_t = it_p, it_t
    it_p = state_p.copy()  # local copies in the loops (the caller's arrays could alias others)
    it_t = state_t.copy()
    while it < iterations:
        if first == 0:
            it_best = -np.inf
        end = _chunk_end(samples, first, budget, used)
        # the hot case n <= 3 has a loop of its own, the general one written again on purpose:
        # numba compiled one loop that could reach either objective 1.7x slower (swarm-3, 5
        # agents: 0.97 -> 0.53 s per step); both draw the same stream and find the same values.
        # As grasp._sample_block's two loops, here inline in the one function that samples
        if 1 <= n <= 3:
            for _s in range(first, end):
                _draw_choice(rng, M, blk, pr, tg)
                xi = kernel_targets_value_unrolled(pz, n, kind, pr, tg, kk)
                if xi > it_best and (not constrained or _feasible(gain, levels_w, delta, C, pr, tg, L)):
                    it_best = xi
                    it_p[:] = pr
                    it_t[:] = tg
        else:
            for _s in range(first, end):
                _draw_choice(rng, M, blk, pr, tg)
                xi = kernel_targets_value(pz, n, kind, pr, tg, kk, p, q)
                if xi > it_best and (not constrained or _feasible(gain, levels_w, delta, C, pr, tg, L)):
                    it_best = xi
                    it_p[:] = pr
                    it_t[:] = tg
        used += end - first
        if end < samples:  # the budget ran out inside this iteration's sampling: pause here
            _pause(fstate, istate, best, it_best, it, end, state_p, state_t, it_p, it_t)
            return False
        first = 0
        if it_best == -np.inf:
            it_best = start
            it_p[:] = start_p
            it_t[:] = start_t
        u = it_p[me] // L
        l0 = it_p[me] % L
        u_minus, u_plus, l_minus, l_plus = kernel_local_neighbourhood(rng, neigh, n_neigh, me, u, l0, L)
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
        it += 1
    fstate[1] = best
    istate[0] = it
    istate[1] = 0
    return True


def _start_value(pz, gain, levels_w, delta, n, kind, constrained, best_pair, best_target) -> float:
    N = best_pair.shape[0]
    C = gain.shape[2] // pz.shape[0]
    return float(_value(pz, gain, levels_w, delta, n, kind, constrained, C, best_pair, best_target,
                        np.empty(N, dtype=np.int64), np.empty(N), np.empty(n + 1)))


def assignment_grasp_chunked(rng, me, pz, gain, levels_w, delta, n, kind, constrained, n_cand, neigh, n_neigh,
                             samples, iterations, best_pair, best_target, stop=None,
                             chunk: int = GRASP_CHUNK_SAMPLES) -> float:
    """Agent ``me``'s search (:func:`kernel_assignment_resume`) from the incumbent in
    ``best_pair`` (c * L + l) and ``best_target`` ((N,), written in place as the search improves
    it), in chunks of ``chunk`` joint samples, answering Ctrl-C between them: any chunk size
    draws the same stream and finds the same plan. Stops early, keeping the best so far, when
    ``stop`` is set. Returns its value."""
    st = GraspState(_start_value(pz, gain, levels_w, delta, n, kind, constrained, best_pair, best_target),
                    best_pair, best_target)
    run_in_chunks(lambda k: kernel_assignment_resume(
        rng, me, pz, gain, levels_w, delta, n, kind, constrained, n_cand, neigh, n_neigh, int(samples),
        int(iterations), st.best_cand, st.best_level, st.start_cand, st.start_level, st.it_c, st.it_l,
        st.fstate, st.istate, int(k)), stop, chunk)
    return st.value


def assignment_grasp_reference(rng, me, problem: AssignmentProblem, neigh, n_neigh, samples, iterations):
    """Plain-numpy twin of :func:`assignment_grasp_chunked` from the starting incumbent (same
    draws, same ties); returns (value, pairs c * L + l, targets). Agent i's choice x is target
    x // blk_i and pair x mod blk_i (blk_i = n_cand_i L)."""
    N, K, L = problem.n_agents, problem.n_targets, problem.n_levels
    blk = problem.n_cand * L

    def values(x):
        v, ok = assignment_value(problem, x % blk // L, x % blk % L, x // blk)
        return np.where(ok, v, -np.inf) if problem.constraints else v

    def neighbourhood(x):
        us, ls = local_neighbourhood_reference(rng, neigh, n_neigh, me, x % blk[me] // L, x % blk[me] % L, L)
        return [k * blk[me] + uu * L + ll for uu in us for ll in ls for k in range(K)]

    best, x = grasp_reference_loop(rng, me, samples, iterations, blk * K, np.zeros(N, dtype=np.int64), values,
                                   neighbourhood)
    return best, x % blk, x // blk


def solve_assignment_grasp(problem: AssignmentProblem, rngs: list[np.random.Generator], samples: int = 10000,
                           iterations: int = 100, neighbours: int = 6, threads: int = 1) -> AssignmentSolution:
    """Every agent runs its search with ``rngs[j]``; all apply the best (ties: lower j);
    ``threads > 1`` runs the searches side by side (same result)."""
    N, L = problem.n_agents, problem.n_levels
    neigh, n_neigh = neighbour_lists(problem.targets[0], neighbours)
    values = np.empty(N)
    pairs = np.zeros((N, N), dtype=np.int64)
    targets = np.zeros((N, N), dtype=np.int64)

    def search(j: int, stop) -> None:
        values[j] = assignment_grasp_chunked(
            rngs[j], j, problem.pz, problem.gain, problem.levels_w, problem.delta_w, problem.at_least,
            problem.kind, problem.constraints, problem.n_cand, neigh, n_neigh, int(samples), int(iterations),
            pairs[j], targets[j], stop,
        )

    search_every_agent(search, rngs, N, threads)
    best = int(np.argmax(values))
    return to_assignment_solution(problem, pairs[best] // L, pairs[best] % L, targets[best])
