"""The joint objective Xi^N_n of Eq. (12) and the interference constraint of Eq. (13).

Xi^N_n = sum_{m=n}^{N} xi^N_m is the probability that at least n of the N agents detect,
the agents detecting independently with probabilities p^1_D..p^N_D: the upper tail of a
Poisson-binomial law. It is computed by dynamic programming over the agents in O(N n), with
state m = 0..n-1 ("exactly m detections so far") and an absorbing state n ("at least n"), so no
subtraction and no sum over subsets. Xi is non-decreasing in every p^j_D, which the exact solver
relies on.

Eq. (13): agent i receives sum_{j != i} l_j g_{j->i}, and must receive strictly less than delta.

Planning over the belief averages Xi over weighted samples of the target's position,
sum_s w_s Xi(p_D at x_s) (:func:`mean_at_least`, accumulated in sample order so that the
compiled solvers reproduce it bit for bit; one sample of weight 1 is Xi itself).

``kernel_at_least`` (its step, ``kernel_add_detector``, also serves the exact solvers' bounds)
and ``kernel_feasible`` are the compiled twins used inside the solvers; ``at_least_probability``
and ``received_interference`` are the numpy references.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from trackjam.control.problem import Problem, Solution


def at_least_probability(p, n: int) -> np.ndarray:
    """Xi^N_n = P(at least n of N detect) for ``p`` of shape (..., N); vectorised numpy."""
    p = np.asarray(p, dtype=np.float64)
    N = p.shape[-1]
    if n <= 0:
        return np.ones(p.shape[:-1])
    if n > N:
        return np.zeros(p.shape[:-1])
    q = np.zeros(p.shape[:-1] + (n + 1,))
    q[..., 0] = 1.0
    for j in range(N):
        pj = p[..., j : j + 1]
        absorbed = q[..., n] + q[..., n - 1] * pj[..., 0]
        q[..., 1:n] = q[..., 1:n] * (1.0 - pj) + q[..., 0 : n - 1] * pj
        q[..., 0] = q[..., 0] * (1.0 - pj[..., 0])
        q[..., n] = absorbed
    return q[..., n]


@njit(cache=True)
def kernel_add_detector(q, n, x):
    """One more agent detecting with probability ``x`` in the truncated count law ``q`` (q[m]
    = P(exactly m) for m < n, q[n] = P(at least n)), in place: the step of the programme."""
    q[n] += q[n - 1] * x
    for m in range(n - 1, 0, -1):
        q[m] = q[m] * (1.0 - x) + q[m - 1] * x
    q[0] *= 1.0 - x


@njit(cache=True)
def kernel_at_least(p, n, q):
    """Compiled twin of :func:`at_least_probability` for one vector ``p`` (N,); ``q`` is a
    work buffer of length >= n + 1."""
    N = p.shape[0]
    if n <= 0:
        return 1.0
    if n > N:
        return 0.0
    q[0] = 1.0
    for m in range(1, n + 1):
        q[m] = 0.0
    for j in range(N):
        kernel_add_detector(q, n, p[j])
    return q[n]


def mean_at_least(p, w, n: int) -> np.ndarray:
    """sum_s w_s Xi^N_n(p[s]) for ``p`` of shape (S, ..., N) and weights ``w`` (S,).

    Xi is computed for every sample at once (its programme is elementwise, so each sample's
    value is the one it has alone), then accumulated in sample order: the per-sample call it
    replaces cost 10 us a sample (a step planned over 48 samples spent 0.4 ms here)."""
    xi = at_least_probability(p, n)
    acc = 0.0
    for s in range(len(w)):
        acc = acc + w[s] * xi[s]
    return np.asarray(acc)


def received_interference(gain, levels_w, cand, level) -> np.ndarray:
    """Left side of Eq. (13): power each agent i receives from the others [W], shape (..., N).

    ``gain`` is :attr:`Problem.gain`; ``cand`` and ``level`` have shape (..., N).
    """
    cand = np.asarray(cand)
    level = np.asarray(level)
    N = gain.shape[0]
    i = np.arange(N)
    # g[..., i, j] = gain[i, j, cand_i, cand_j]
    g = gain[i[:, None], i[None, :], cand[..., :, None], cand[..., None, :]]
    return np.sum(g * np.asarray(levels_w)[level][..., None, :], axis=-1)


@njit(cache=True)
def kernel_feasible(gain, levels_w, delta, cand, level):
    """Compiled Eq. (13): True when every agent receives strictly less than ``delta``."""
    N = cand.shape[0]
    for i in range(N):
        r = 0.0
        for j in range(N):
            if j != i:
                r += levels_w[level[j]] * gain[i, j, cand[i], cand[j]]
        if r >= delta:
            return False
    return True


def evaluate(problem: Problem, cand, level) -> tuple[np.ndarray, np.ndarray]:
    """Xi^N_n (averaged over the belief's samples when the problem has them) and Eq. (13) of
    joint choices (``cand``, ``level`` of shape (..., N)).

    The second array says whether Eq. (13) holds, whether or not ``problem.constraints`` asks
    the solvers to enforce it (so a solution can report honestly that it jams an agent).
    """
    cand = np.asarray(cand, dtype=np.int64)
    level = np.asarray(level, dtype=np.int64)
    N = problem.n_agents
    p_s, w = problem.objective_tables()
    xi = mean_at_least(p_s[:, np.arange(N), cand, level], w, problem.at_least)
    ok = np.all(received_interference(problem.gain, problem.levels_w, cand, level) < problem.delta_w, axis=-1)
    return xi, ok


def to_solution(problem: Problem, cand, level) -> Solution:
    """The :class:`Solution` of candidate slots ``cand`` and levels ``level``, re-evaluated."""
    cand = np.asarray(cand, dtype=np.int64)
    level = np.asarray(level, dtype=np.int64)
    xi, ok = evaluate(problem, cand, level)
    move = problem.move[np.arange(problem.n_agents), cand]
    return Solution(move=move, level=level.copy(), objective=float(xi), feasible=bool(ok))
