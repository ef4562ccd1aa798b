"""The paper's distributed GRASP (Section V-D), as docs/model.md reads it.

Each agent j, with its own random stream, runs n_I iterations of

1. *greedy randomised solution*: n_s joint controls, each agent's (candidate, level) pair drawn
   uniformly with replacement from its admissible pairs; the best feasible one (Eqs. 12-13) is
   kept (the first in sample order among equal values);
2. *local search*: agent j alone tries {u-, u, u+} x {l-, l, l+} around its own control, the
   others' fixed, where u-, u+ are two distinct controls drawn at random among the
   ``neighbours`` admissible displacements nearest to u (Euclidean distance between
   displacement vectors, ties to the lower index) and l-, l+ the adjacent levels, clipped at the
   ends of L; a neighbour replaces the incumbent only when strictly better;

and keeps the best feasible control over its iterations. The agents then exchange their best
solutions and all apply the best one (ties to the lower agent index). Planning over the belief,
every value is the objective averaged over the samples (``Problem.objective_tables``).

All agents hovering at the lowest level (``off`` in the paper, 0 W, hence no interference) is
the starting incumbent of every search, so a feasible solution is always returned when level 0
is off. An iteration whose n_s samples are all infeasible searches around that incumbent.

Random draws (ours, to make the compiled and numpy versions draw the same stream): a uniform
pair out of M is ``floor(U * M)`` with U = ``rng.random()`` (a bias below M / 2^53); the samples
of an iteration take U row by row (sample-major, agent-minor), then the local search takes two
more: a = floor(U1 m), b = floor(U2 (m - 1)), b += 1 if b >= a, for the m neighbours of u.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence

import numpy as np
from numba import njit

from trackjam.control.objective import (
    kernel_at_least,
    mean_at_least,
    kernel_feasible,
    received_interference,
    to_solution,
)
from trackjam.control.problem import Problem, Solution


def neighbour_lists(problem: Problem, neighbours: int) -> tuple[np.ndarray, np.ndarray]:
    """For every agent's candidate, the slots of its ``neighbours`` nearest other candidates.

    Returns ``neigh`` (N, C, k) and ``n_neigh`` (N, C), ``n_neigh = min(neighbours, n_cand-1)``.
    Distance is between displacement vectors; ties go to the lower displacement index.
    """
    N, C = problem.move.shape
    k = max(int(neighbours), 1)
    neigh = np.zeros((N, C, k), dtype=np.int64)
    n_neigh = np.zeros((N, C), dtype=np.int64)
    for i in range(N):
        n = int(problem.n_cand[i])
        d = problem.displacements[problem.move[i, :n]]
        dist = np.linalg.norm(d[:, None, :] - d[None, :, :], axis=-1)
        dist[np.arange(n), np.arange(n)] = np.inf
        order = np.argsort(dist, axis=1, kind="stable")[:, : min(k, n - 1)]
        neigh[i, :n, : order.shape[1]] = order
        n_neigh[i, :n] = order.shape[1]
    return neigh, n_neigh


@njit(cache=True, nogil=True)
def kernel_local_neighbourhood(rng, neigh, n_neigh, me, u, l0, L):
    """The local search's (u-, u+, l-, l+) around agent ``me``'s control (u, l0): two distinct
    of u's ``n_neigh`` neighbours drawn with two ``rng.random()`` (the module docstring), u's
    only neighbour twice when it has one, u itself when none (no draw then); the adjacent levels
    clipped at the ends of L levels."""
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
    return u_minus, u_plus, max(l0 - 1, 0), min(l0 + 1, L - 1)


def local_neighbourhood_reference(rng, neigh, n_neigh, me, u, l0, L) -> tuple[list, list]:
    """Plain twin of :func:`kernel_local_neighbourhood` (same draws): ([u-, u, u+], [l-, l0, l+]),
    u+ drawn uniformly from the neighbours other than u-."""
    near = [int(v) for v in neigh[me, u, : n_neigh[me, u]]]
    levels = [int(v) for v in np.clip([l0 - 1, l0, l0 + 1], 0, L - 1)]
    if len(near) < 2:
        one = near[0] if near else u
        return [one, u, one], levels
    U = rng.random(2)
    a = min(int(U[0] * len(near)), len(near) - 1)
    rest = near[:a] + near[a + 1:]
    return [near[a], u, rest[min(int(U[1] * len(rest)), len(rest) - 1)]], levels


@njit(cache=True)
def _value(p_s, w, gain, levels_w, delta, n, constrained, cand, level, p, q):
    """sum_s w_s Xi of (cand, level), or -inf when Eq. (13) is enforced and violated."""
    if constrained and not kernel_feasible(gain, levels_w, delta, cand, level):
        return -np.inf
    xi = 0.0
    for s in range(w.shape[0]):
        for i in range(cand.shape[0]):
            p[i] = p_s[s, i, cand[i], level[i]]
        xi += w[s] * kernel_at_least(p, n, q)
    return xi


@njit(cache=True, nogil=True, inline="always")
def _xi_unrolled(p_flat, kk, n):
    """Xi^N_n of the pairs ``kk`` for 1 <= n <= min(3, N): :func:`kernel_at_least`'s recursion,
    same operations in the same order (so bit-identical), unrolled into scalars (3x faster than
    the general recursion over an array). It takes no work arrays: with a call that could also
    reach the general recursion in its sampling loop, the whole GRASP search was 2.4x slower.
    The caller guarantees 1 <= n <= min(3, N): any other n is computed as n = 3."""
    N = kk.shape[0]
    if n == 1:
        q0, q1 = 1.0, 0.0
        for j in range(N):
            pj = p_flat[j, kk[j]]
            q1 += q0 * pj
            q0 *= 1.0 - pj
        return q1
    if n == 2:
        q0, q1, q2 = 1.0, 0.0, 0.0
        for j in range(N):
            pj = p_flat[j, kk[j]]
            q2 += q1 * pj
            q1 = q1 * (1.0 - pj) + q0 * pj
            q0 *= 1.0 - pj
        return q2
    # n == 3 (the callers guarantee 1 <= n <= min(3, N); an explicit test here would cost speed)
    q0, q1, q2, q3 = 1.0, 0.0, 0.0, 0.0
    for j in range(N):
        pj = p_flat[j, kk[j]]
        q3 += q2 * pj
        q2 = q2 * (1.0 - pj) + q1 * pj
        q1 = q1 * (1.0 - pj) + q0 * pj
        q0 *= 1.0 - pj
    return q3


@njit(cache=True, nogil=True, inline="always")
def _sample_xi(p_flat, kk, n, p, q):
    """Xi^N_n of the pairs ``kk`` for any n: :func:`_xi_unrolled` for 1 <= n <= 3, else
    :func:`kernel_at_least` on the work arrays ``p`` (N,) and ``q`` (n + 1,)."""
    N = kk.shape[0]
    if n <= 0:
        return 1.0
    if n > N:
        return 0.0
    if n <= 3:
        return _xi_unrolled(p_flat, kk, n)
    for j in range(N):
        p[j] = p_flat[j, kk[j]]
    return kernel_at_least(p, n, q)


@njit(cache=True, nogil=True, inline="always")
def _resumed(fstate, istate):
    """The state a resumable search (:func:`kernel_grasp_resume`) left between calls: (value of
    the start, best value, value of the iteration's best sample, iteration, sample)."""
    return fstate[0], fstate[1], fstate[2], istate[0], istate[1]


@njit(cache=True, nogil=True, inline="always")
def _chunk_end(samples, first, budget, used):
    """Where this call samples the current iteration up to: its end, or where ``budget`` joint
    samples, ``used`` of them already drawn by the call, run out."""
    return samples if budget - used >= samples - first else first + (budget - used)


@njit(cache=True, nogil=True, inline="always")
def _pause(fstate, istate, best, it_best, it, sample, state_a, state_b, it_a, it_b):
    """Keep a resumable search's state when its budget runs out at ``sample`` of iteration
    ``it``: the values, the position, and the iteration's best sample ``it_a``/``it_b`` in the
    caller's ``state_a``/``state_b``."""
    fstate[1] = best
    fstate[2] = it_best
    istate[0] = it
    istate[1] = sample
    state_a[:] = it_a
    state_b[:] = it_b


@njit(cache=True, nogil=True)
def _sample_block(rng, p_flat, w, M, n, first, end, kk, c, lv, p, q, gain, levels_w, delta, constrained,
                  pair_c, pair_l, it_c, it_l, it_best):
    """Samples ``first`` to ``end`` of an iteration's greedy randomised solution (step 1 of the
    module docstring): returns the best feasible value so far, its control in ``it_c``/``it_l``.

    The hot case, one sample of the objective and 1 <= n <= min(3, N), has a loop of its own
    that calls :func:`_xi_unrolled` alone. Both loops draw the same stream and find the same
    values; the second is the first written again on purpose: the whole search with one loop
    that branches to either evaluation was 1.6x slower, with a helper that keeps a better sample
    1.9x (numba 0.68, three agents, 79 controls)."""
    N = M.shape[0]
    S = w.shape[0]
    if S == 1 and 1 <= n <= min(3, N):
        p_first = p_flat[0]
        for _s in range(first, end):
            for i in range(N):
                kk[i] = min(int(rng.random() * M[i]), M[i] - 1)
            xi = _xi_unrolled(p_first, kk, n)
            if xi > it_best:
                for i in range(N):
                    c[i] = pair_c[kk[i]]
                    lv[i] = pair_l[kk[i]]
                if not constrained or kernel_feasible(gain, levels_w, delta, c, lv):
                    it_best = xi
                    it_c[:] = c
                    it_l[:] = lv
        return it_best
    for _s in range(first, end):
        for i in range(N):
            kk[i] = min(int(rng.random() * M[i]), M[i] - 1)
        if S == 1:  # w = [1]
            xi = _sample_xi(p_flat[0], kk, n, p, q)
        else:
            xi = 0.0
            for s in range(S):
                xi += w[s] * _sample_xi(p_flat[s], kk, n, p, q)
        if xi > it_best:
            for i in range(N):
                c[i] = pair_c[kk[i]]
                lv[i] = pair_l[kk[i]]
            if not constrained or kernel_feasible(gain, levels_w, delta, c, lv):
                it_best = xi
                it_c[:] = c
                it_l[:] = lv
    return it_best


@njit(cache=True, nogil=True)
def kernel_grasp_resume(rng, me, p_s, w, gain, levels_w, delta, n, constrained, n_cand, neigh, n_neigh,
                        samples, iterations, best_cand, best_level, start_cand, start_level, it_c, it_l,
                        fstate, istate, budget):
    """Agent ``me``'s GRASP search, resumable: it runs until ``budget`` more joint samples are
    drawn (the local searches are not counted) or the search ends, and returns True when it has
    ended. Its state between calls: the best control so far in ``best_cand``/``best_level``
    ((N,), on the first call the starting incumbent, also in ``start_cand``/``start_level``),
    the current iteration's best sample in ``it_c``/``it_l``, ``fstate`` = [value of the start,
    best value, value of the iteration's best sample] and ``istate`` = [iteration, sample]
    (both 0 on the first call). Calls of any budgets draw the same stream and give the same
    result as one call: the Python side checks Ctrl-C and a stop flag between calls.
    ``p_s`` (S, N, C, L) and ``w`` (S,) are :meth:`Problem.objective_tables`."""
    N = n_cand.shape[0]
    S = w.shape[0]
    L = levels_w.shape[0]
    p = np.empty(N)
    q = np.empty(n + 1)
    c = np.empty(N, dtype=np.int64)
    lv = np.empty(N, dtype=np.int64)
    kk = np.empty(N, dtype=np.int64)
    M = n_cand * L
    p_flat = p_s.reshape(S, N, -1)  # pair k = c * L + l
    pair_c = np.arange(p_flat.shape[2]) // L
    pair_l = np.arange(p_flat.shape[2]) % L
    start, best, it_best, it, first = _resumed(fstate, istate)
    used = 0
    state_c, state_l = it_c, it_l
    it_c = state_c.copy()  # local copies in the loops (the caller's arrays could alias others)
    it_l = state_l.copy()
    while it < iterations:
        # 1. greedy randomised solution: best feasible of n_s uniform joint samples
        if first == 0:
            it_best = -np.inf
        end = _chunk_end(samples, first, budget, used)
        it_best = _sample_block(rng, p_flat, w, M, n, first, end, kk, c, lv, p, q, gain, levels_w, delta,
                                constrained, pair_c, pair_l, it_c, it_l, it_best)
        used += end - first
        if end < samples:  # the budget ran out inside this iteration's sampling: pause here
            _pause(fstate, istate, best, it_best, it, end, state_c, state_l, it_c, it_l)
            return False
        first = 0
        if it_best == -np.inf:
            it_best = start
            it_c[:] = start_cand
            it_l[:] = start_level
        # 2. local search over my own {u-, u, u+} x {l-, l, l+}
        u = it_c[me]
        l0 = it_l[me]
        u_minus, u_plus, l_minus, l_plus = kernel_local_neighbourhood(rng, neigh, n_neigh, me, u, l0, L)
        c[:] = it_c
        lv[:] = it_l
        ls_best = it_best
        ls_u, ls_l = u, l0
        for uu in (u_minus, u, u_plus):
            for ll in (l_minus, l0, l_plus):
                c[me] = uu
                lv[me] = ll
                v = _value(p_s, w, gain, levels_w, delta, n, constrained, c, lv, p, q)
                if v > ls_best:
                    ls_best = v
                    ls_u, ls_l = uu, ll
        if ls_best > best:
            best = ls_best
            best_cand[:] = it_c
            best_level[:] = it_l
            best_cand[me] = ls_u
            best_level[me] = ls_l
        it += 1
    fstate[1] = best
    istate[0] = it
    istate[1] = 0
    return True


class GraspState:
    """One agent's resumable GRASP search (:func:`kernel_grasp_resume`) from the incumbent in
    ``best_cand``/``best_level`` (written in place as the search improves it)."""

    def __init__(self, start_value: float, best_cand: np.ndarray, best_level: np.ndarray) -> None:
        self.best_cand, self.best_level = best_cand, best_level
        self.start_cand, self.start_level = best_cand.copy(), best_level.copy()
        self.it_c, self.it_l = best_cand.copy(), best_level.copy()
        self.fstate = np.array([start_value, start_value, -np.inf])
        self.istate = np.zeros(2, dtype=np.int64)

    @property
    def value(self) -> float:
        return float(self.fstate[1])


#: joint samples a compiled GRASP call draws before it returns to Python, which then answers
#: Ctrl-C and a stop flag (about 0.03-0.1 s for N = 3; the default search, 10^4 x 100, is one call)
GRASP_CHUNK_SAMPLES = 1_000_000


def run_in_chunks(step: Callable[[int], bool], stop: threading.Event | None = None,
                  chunk: int = GRASP_CHUNK_SAMPLES) -> bool:
    """Call ``step(chunk)`` until it returns True (the search ended) or ``stop`` is set; True
    when it ended. Between calls Python runs, so Ctrl-C is answered within one chunk."""
    while not step(chunk):
        if stop is not None and stop.is_set():
            return False
    return True


def grasp_search_chunked(rng, me, problem_tables, gain, levels_w, delta, n, constrained, n_cand, neigh, n_neigh,
                         samples, iterations, best_cand, best_level, stop: threading.Event | None = None,
                         chunk: int = GRASP_CHUNK_SAMPLES) -> float:
    """Agent ``me``'s GRASP search (:func:`kernel_grasp_resume`) from the incumbent in
    ``best_cand``/``best_level`` ((N,), written in place as the search improves it), in chunks
    of ``chunk`` joint samples: any chunk size draws the same stream and finds the same plan.
    Stops early, keeping the best so far, when ``stop`` is set. Returns its value (-inf: none
    feasible). ``problem_tables`` is :meth:`Problem.objective_tables`."""
    p_s, w = problem_tables
    N = n_cand.shape[0]
    start = _value(p_s, w, gain, levels_w, delta, n, constrained, best_cand, best_level, np.empty(N),
                   np.empty(n + 1))
    st = GraspState(start, best_cand, best_level)
    run_in_chunks(lambda k: kernel_grasp_resume(
        rng, me, p_s, w, gain, levels_w, delta, n, constrained, n_cand, neigh, n_neigh, int(samples),
        int(iterations), st.best_cand, st.best_level, st.start_cand, st.start_level, st.it_c, st.it_l,
        st.fstate, st.istate, int(k)), stop, chunk)
    return st.value


def grasp_reference_loop(rng, me, samples, iterations, n_choices, start, values, neighbourhood):
    """The plain-numpy GRASP of agent ``me`` over joint choices x (N,), agent i's x_i in
    [0, n_choices[i]): ``values(x)`` scores joint choices (..., N) (-inf: infeasible),
    ``neighbourhood(x_me)`` lists (drawing from ``rng``) agent me's local-search choices in trial
    order. The twins of both compiled searches; returns (value, x)."""
    start = np.array(start)
    best_x = start.copy()
    start_value = best = float(values(start))
    for _ in range(iterations):
        U = rng.random((samples, len(n_choices)))
        x = np.minimum((U * n_choices).astype(np.int64), n_choices - 1)
        v = values(x)
        s = int(np.argmax(v))
        if v[s] == -np.inf:
            it_best, it_x = start_value, start.copy()
        else:
            it_best, it_x = float(v[s]), x[s].copy()
        options = neighbourhood(it_x[me])
        trials = np.tile(it_x, (len(options), 1))
        trials[:, me] = options
        tv = values(trials)
        t = int(np.argmax(tv))
        if tv[t] > it_best:
            it_best, it_x = float(tv[t]), trials[t]
        if it_best > best:
            best, best_x = it_best, it_x.copy()
    return best, best_x


def grasp_search_reference(rng, me, problem: Problem, neigh, n_neigh, samples, iterations,
                           start_cand, start_level):
    """Plain-numpy twin of :func:`grasp_search_chunked` (same draws, same ties); returns (value,
    candidate slots, levels)."""
    N, L, n = problem.n_agents, problem.n_levels, problem.at_least
    idx = np.arange(N)
    p_s, w = problem.objective_tables()

    def values(k):
        c, lv = k // L, k % L
        xi = mean_at_least(p_s[:, idx, c, lv], w, n)
        if problem.constraints:
            ok = np.all(received_interference(problem.gain, problem.levels_w, c, lv) < problem.delta_w, axis=-1)
            xi = np.where(ok, xi, -np.inf)
        return xi

    def neighbourhood(k):
        us, ls = local_neighbourhood_reference(rng, neigh, n_neigh, me, k // L, k % L, L)
        return [uu * L + ll for uu in us for ll in ls]

    start = np.asarray(start_cand) * L + np.asarray(start_level)
    best, k = grasp_reference_loop(rng, me, samples, iterations, problem.n_cand * L, start, values, neighbourhood)
    return best, k // L, k % L


def search_every_agent(search: Callable[[int, threading.Event], None], rngs: Sequence[np.random.Generator],
                       n_agents: int, threads: int) -> None:
    """Run every agent's ``search(j, stop)`` (agent j draws from ``rngs[j]``); ``threads > 1`` runs
    them side by side (they are independent, as on the real team, so the result does not depend
    on it). On Ctrl-C (or any error) ``stop`` is set, so that searches running in other threads
    end at their next chunk instead of running on."""
    if len(rngs) < n_agents:
        raise ValueError(f"grasp needs one random generator per agent ({n_agents}), got {len(rngs)}")
    run_searches(search, n_agents, threads)


def run_searches(search: Callable[[int, threading.Event], None], n: int, threads: int) -> None:
    """``search(k, stop)`` for k in 0..n-1, in up to ``threads`` threads; ``stop`` is set when the
    caller is interrupted (Ctrl-C) or one search fails, before waiting for the others."""
    stop = threading.Event()
    if threads > 1 and n > 1:
        with ThreadPoolExecutor(max_workers=min(threads, n)) as pool:
            futures = [pool.submit(search, k, stop) for k in range(n)]
            try:
                for f in futures:
                    f.result()
            except BaseException:
                stop.set()
                raise
    else:
        for k in range(n):
            search(k, stop)


def solve_grasp(problem: Problem, rngs: list[np.random.Generator], samples: int = 10000,
                iterations: int = 100, neighbours: int = 6, threads: int = 1) -> Solution:
    """Every agent runs its GRASP search with ``rngs[j]``; all apply the best (ties: lower j).

    ``threads > 1`` runs the agents' searches concurrently (they are independent, as on the
    real team, so the result does not depend on it).
    """
    N = problem.n_agents
    neigh, n_neigh = neighbour_lists(problem, neighbours)
    p_s, w = problem.objective_tables()
    values = np.empty(N)
    cands = np.zeros((N, N), dtype=np.int64)
    levels = np.zeros((N, N), dtype=np.int64)

    def search(j: int, stop: threading.Event) -> None:
        values[j] = grasp_search_chunked(
            rngs[j], j, (p_s, w), problem.gain, problem.levels_w, problem.delta_w,
            problem.at_least, problem.constraints, problem.n_cand, neigh, n_neigh,
            int(samples), int(iterations), cands[j], levels[j], stop,
        )

    search_every_agent(search, rngs, N, threads)
    best = int(np.argmax(values))
    return to_solution(problem, cands[best], levels[best])
