"""One step's decision for K targets (ours, issue 12): each agent picks a move, a level and the
target its cone serves.

Agent i serving target k aims its cone at x_bar_k, so its p_D (Eq. 9 at x_bar_k) counts for
target k only, and its cone aimed at x_bar_k is what Eq. (13) checks at the other agents; which
target an agent serves changes the interference only through that pointing direction.

Per target, n applies as n_k = min(n, m_k), m_k the number of agents serving k (every agent
serves one target, whatever its level): Xi_k = P(at least n_k of the m_k agents serving k
detect k), and Xi_k = 0 for a target nobody serves. Fewer servers than n must therefore all
detect, so below n each added server lowers Xi_k (n = 2: one server gives p_1, two p_1 p_2);
from n servers on, each added one raises it. The team objective is
``sum`` (sum_k Xi_k) or ``min`` (min_k Xi_k: no target left alone; 0 whenever N < K). With one
target (m_1 = N >= n) both are Eq. (12)'s Xi^N_n, bit for bit.

The tables reuse the one-target ones: ``targets[k]`` is :func:`build_problem` at x_bar_k (the
same candidates for every k), and the solvers see an *extended candidate* v = k * C + c (the
slot c aimed at x_bar_k), whose gain table ``gain[i, j, vi, vj]`` = ``targets[kj].gain[i, j, ci,
cj]`` (the receiver's aim does not matter) lets the one-target Eq. (13) kernels run unchanged.
``pz[k, i, c * L + l]`` is p_D of agent i at (c, l) serving k, with a last column of zeros for
"not serving k": Xi_k is the one-target Xi of the padded vector, and a p_D of 0 leaves the
recursion's numbers exactly as they were, which is why K = 1 reproduces Eq. (12) bit for bit.

``kernel_targets_value`` is the compiled objective; ``assignment_value`` its numpy twin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from trackjam.control.grasp import _sample_xi, _xi_unrolled
from trackjam.control.greedy import greedy_choice
from trackjam.control.objective import at_least_probability, received_interference
from trackjam.control.problem import Problem, build_problem
from trackjam.radio.antenna import AntennaModel

#: team objectives over the targets, by name; the kernels take the index
OBJECTIVES = ("sum", "min")


@dataclass(frozen=True)
class AssignmentProblem:
    """The arrays of one planning step with K aims (N agents, C padded candidates, L levels)."""

    targets: tuple[Problem, ...]  # one-target problems, one per aim x_bar_k, same candidates
    objective: str  # "sum" or "min" over the targets
    gain: np.ndarray  # (N, N, K*C, K*C) Eq. (13)'s gains over extended candidates v = k*C + c
    pz: np.ndarray  # (K, N, C*L + 1) p_D of pair c*L + l serving k; last column 0 (not serving)

    @property
    def n_agents(self) -> int:
        return self.targets[0].n_agents

    @property
    def n_targets(self) -> int:
        return len(self.targets)

    @property
    def n_levels(self) -> int:
        return self.targets[0].n_levels

    @property
    def n_slots(self) -> int:
        """C, the padded number of candidates per agent."""
        return int(self.targets[0].move.shape[1])

    @property
    def kind(self) -> int:
        return OBJECTIVES.index(self.objective)

    @property
    def at_least(self) -> int:
        return self.targets[0].at_least

    @property
    def constraints(self) -> bool:
        return self.targets[0].constraints

    @property
    def levels_w(self) -> np.ndarray:
        return self.targets[0].levels_w

    @property
    def delta_w(self) -> float:
        return self.targets[0].delta_w

    @property
    def n_cand(self) -> np.ndarray:
        return self.targets[0].n_cand


@dataclass(frozen=True)
class AssignmentSolution:
    """A joint control for K targets: every agent's displacement, level and served target."""

    move: np.ndarray  # (N,) index into the displacement set (0 = hover)
    level: np.ndarray  # (N,) index into antenna.levels_w
    target: np.ndarray  # (N,) index k of the aim the agent's cone serves
    objective: float  # the team objective (sum or min of xi)
    xi: np.ndarray  # (K,) Xi_k of every target
    feasible: bool  # Eq. (13) holds for every agent (reported even when constraints are off)
    optimal: bool = False  # proven optimal (only `exact` proves it, when its budget suffices)
    gap: float = float("nan")  # certified bound on (optimum - objective); NaN: no certificate
    nodes: int = 0  # branch-and-bound nodes visited (`exact`)


def build_assignment(positions, aims, displacements, antenna: AntennaModel, low, high, at_least: int,
                     constraints: bool, objective: str = "sum") -> AssignmentProblem:
    """Precompute one step's problem for the aims x_bar_1..x_bar_K (``aims`` of shape (K, 3)).

    Raises ``ValueError`` on an unknown objective, no aim or a non-finite one, and whatever
    :func:`build_problem` refuses (an agent outside the area, n outside 1..N).
    """
    if objective not in OBJECTIVES:
        raise ValueError(f"unknown team objective {objective!r}; expected one of {', '.join(OBJECTIVES)}")
    x = np.asarray(aims, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] != 3 or not np.all(np.isfinite(x)):
        raise ValueError(f"aims must be finite positions of shape (K, 3) with K >= 1, got shape {x.shape}")
    targets = tuple(build_problem(positions, a, displacements, antenna, low, high, at_least, constraints)
                    for a in x)
    G = np.stack([t.gain for t in targets])  # (K, N, N, C, C): sender's aim k
    K, N, _, C, _ = G.shape
    # gain[i, j, ki, ci, kj, cj] = G[kj, i, j, ci, cj]
    g = np.broadcast_to(G.transpose(1, 2, 3, 0, 4)[:, :, None], (N, N, K, C, K, C))
    L = targets[0].n_levels
    pz = np.zeros((K, N, C * L + 1))
    pz[:, :, :-1] = np.stack([t.p_d for t in targets]).reshape(K, N, C * L)
    return AssignmentProblem(targets=targets, objective=objective,
                             gain=np.ascontiguousarray(g.reshape(N, N, K * C, K * C)), pz=pz)


def target_xi(problem: AssignmentProblem, cand, level, target) -> np.ndarray:
    """Xi_k of joint choices (``cand``, ``level``, ``target`` of shape (..., N)), shape (..., K);
    plain numpy (the reference of the compiled objective)."""
    cand, level, target = (np.asarray(a, dtype=np.int64) for a in (cand, level, target))
    N, n = problem.n_agents, problem.at_least
    out = []
    for k, P in enumerate(problem.targets):
        mine = target == k
        p = np.where(mine, P.p_d[np.arange(N), cand, level], 0.0)
        m = mine.sum(axis=-1)
        xi = np.zeros(m.shape)
        for nk in range(1, n + 1):
            rule = (m == nk) if nk < n else (m >= n)
            xi = np.where(rule, at_least_probability(p, nk), xi)
        out.append(xi)
    return np.stack(out, axis=-1)


def assignment_value(problem: AssignmentProblem, cand, level, target) -> tuple[np.ndarray, np.ndarray]:
    """The team objective and Eq. (13) (True: it holds) of joint choices of shape (..., N)."""
    xi = target_xi(problem, cand, level, target)
    value = np.zeros(xi.shape[:-1]) if problem.objective == "sum" else np.full(xi.shape[:-1], np.inf)
    for k in range(problem.n_targets):  # in target order, as the kernel
        value = value + xi[..., k] if problem.objective == "sum" else np.minimum(value, xi[..., k])
    v = np.asarray(target, dtype=np.int64) * problem.n_slots + np.asarray(cand, dtype=np.int64)
    ok = np.all(received_interference(problem.gain, problem.levels_w, v, level) < problem.delta_w, axis=-1)
    return value, ok


@njit(cache=True, nogil=True, inline="always")
def _served(pair, target, k, zero, kk):
    """Target k's view of a joint choice: ``kk[i]`` agent i's pair when it serves k, else the
    ``zero`` slot (p_D 0); returns how many agents serve k."""
    m = 0
    for i in range(pair.shape[0]):
        if target[i] == k:
            kk[i] = pair[i]
            m += 1
        else:
            kk[i] = zero
    return m


@njit(cache=True, nogil=True, inline="always")
def kernel_targets_value(pz, n, kind, pair, target, kk, p, q):
    """Compiled team objective of one joint choice (``pair[i]`` = c * L + l, ``target`` (N,));
    ``kk`` (N,), ``p`` (N,) and ``q`` (n + 1,) are work buffers."""
    K = pz.shape[0]
    if K == 1:  # every agent serves the one target: Eq. (12) itself
        return _sample_xi(pz[0], pair, n, p, q)
    zero = pz.shape[2] - 1
    acc = 0.0 if kind == 0 else np.inf
    for k in range(K):
        m = _served(pair, target, k, zero, kk)
        x = 0.0 if m == 0 else _sample_xi(pz[k], kk, min(n, m), p, q)
        if kind == 0:
            acc += x
        else:
            acc = min(acc, x)
    return acc


@njit(cache=True, nogil=True, inline="always")
def kernel_targets_value_unrolled(pz, n, kind, pair, target, kk):
    """:func:`kernel_targets_value` for 1 <= n <= 3, the same operations (so bit-identical)
    through :func:`~trackjam.control.grasp._xi_unrolled` alone, with no work arrays: the
    sampling loop of :func:`~trackjam.control.assignment_grasp.kernel_assignment_resume` that
    calls it made the search 1.7 times faster than with the general objective."""
    K, N = pz.shape[0], pz.shape[1]
    if K == 1:
        return 0.0 if n > N else _xi_unrolled(pz[0], pair, n)
    zero = pz.shape[2] - 1
    acc = 0.0 if kind == 0 else np.inf
    for k in range(K):
        m = _served(pair, target, k, zero, kk)
        x = 0.0 if m == 0 else _xi_unrolled(pz[k], kk, min(n, m))
        if kind == 0:
            acc += x
        else:
            acc = min(acc, x)
    return acc


def to_assignment_solution(problem: AssignmentProblem, cand, level, target) -> AssignmentSolution:
    """The :class:`AssignmentSolution` of candidate slots, levels and targets, re-evaluated."""
    cand, level, target = (np.array(a, dtype=np.int64) for a in (cand, level, target))
    value, ok = assignment_value(problem, cand, level, target)
    move = problem.targets[0].move[np.arange(problem.n_agents), cand]
    return AssignmentSolution(move=move, level=level, target=target, objective=float(value),
                              xi=target_xi(problem, cand, level, target), feasible=bool(ok))


def solve_assignment_greedy(problem: AssignmentProblem) -> AssignmentSolution:
    """Eq. (11) with a choice of target: each agent alone takes its best p_D over (move, level,
    target); ties to the lower target (within a target, :func:`greedy_choice`'s ties)."""
    N = problem.n_agents
    choices = [greedy_choice(P) for P in problem.targets]
    score = np.stack([P.p_d[np.arange(N), c, l] for P, (c, l) in zip(problem.targets, choices)])  # (K, N)
    target = np.argmax(score, axis=0)
    cand = np.array([choices[k][0][i] for i, k in enumerate(target)])
    level = np.array([choices[k][1][i] for i, k in enumerate(target)])
    return to_assignment_solution(problem, cand, level, target)
