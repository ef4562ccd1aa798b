"""The distributed decision of Section V-D: every agent searches the joint problem it knows,
announces its best plan, and every agent adopts the best plan it received.

Each agent's own search: ``grasp`` with the agent's own random stream and the agent as the
searcher (``me``), as in the paper; ``exact`` and ``greedy`` are deterministic, so agents
holding the same problem reach the same plan (it is computed once per distinct problem).
The adoption rule every agent applies to the same messages: the highest announced objective,
ties to the lowest sender; a plan without a value (the hover fall-back) ranks below any value.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from trackjam.control.grasp import grasp_search_chunked, neighbour_lists, run_searches
from trackjam.control.objective import to_solution
from trackjam.control.problem import Problem, Solution
from trackjam.control.solve import solve


@dataclass(frozen=True)
class Proposal:
    """A plan one agent announces: controls for the agents it planned for."""

    sender: int
    agents: tuple[int, ...]  # team indices the plan covers, in problem-row order
    mode: str  # "track" | "search" | "hover"
    aim: np.ndarray | None  # where the plan's cones aim (x_bar or the search point); None: each its own
    moves: np.ndarray  # (len(agents),) displacement indices
    levels: np.ndarray  # (len(agents),) level indices
    objective: float  # Xi of the plan at its aim; NaN when it has none
    optimal: bool = False  # proven optimal (exact within its budget)
    gap: float = float("nan")  # certified bound on optimum - objective; NaN: no certificate
    closed_in: bool = False  # control.close_in: the plan closes in (ours)

    def control_of(self, agent: int) -> tuple[int, int]:
        k = self.agents.index(agent)
        return int(self.moves[k]), int(self.levels[k])


def own_searches(problem: Problem, solver: str, rows: Sequence[int], rngs: Sequence[np.random.Generator],
                 samples: int, iterations: int, neighbours: int, threads: int = 1,
                 time_limit_s: float | None = 1.0, node_limit: int = 0,
                 close_in: float | None = None) -> list[tuple[Solution, float]]:
    """The plan each searching agent (problem row ``rows[k]``, stream ``rngs[k]``) finds, with
    the value it announces (GRASP: its search's own value, which ranks the plans as the paper's
    all-apply-the-best does).

    ``close_in`` (``control.close_in``, ours): a searcher whose plan is worth less than this
    (its announced value: Xi, or its mean over the belief's samples) solves twice more: the
    problem without Eq. (13) with its own solver and stream, for the moves, then, unless those
    are its plan's moves already, the levels alone under Eq. (13) with every agent held at its
    move (:meth:`Problem.fixed_at`), with ``exact`` (L^N level vectors: small, and proven
    optimal there). It announces that plan and its value. When Eq. (13) forbids
    every plan that brings the agents closer, the constrained optimum may spread them away
    from the target for a sliver of Xi, step after step; the unconstrained optimum takes each
    agent where its own p_D is highest, and Eq. (13) is then kept by the levels alone (all
    off is always feasible). With ``exact``, ``time_limit_s`` is the budget of all three solves:
    a searcher that has used it up keeps its plan; with GRASP, which it does not bound, it is
    the budget of the levels' solve alone."""
    t0 = time.perf_counter()
    found = _searches(problem, solver, rows, rngs, samples, iterations, neighbours, threads, time_limit_s, node_limit)
    if close_in is None or not problem.constraints:
        return found
    low = [k for k, (_, value) in enumerate(found) if value < close_in]
    if not low:
        return found

    def left() -> float | None:  # exact's budget still unspent [s]; None: none
        if time_limit_s is None or solver != "exact":
            return time_limit_s
        return time_limit_s - (time.perf_counter() - t0)

    def spent() -> bool:
        return time_limit_s is not None and left() <= 0.0

    if spent():
        return found
    # the moves: the problem without Eq. (13), GRASP's low searchers side by side, each with its
    # own stream (a deterministic solver solves it once for all of them)
    budget = (samples, iterations, neighbours, threads)
    frees = _searches(replace(problem, constraints=False), solver, [rows[k] for k in low], [rngs[k] for k in low],
                      *budget, left(), node_limit)
    levels: dict[bytes, tuple[Solution, float]] = {}  # the levels' solve, once per distinct moves
    for k, (free, _) in zip(low, frees):
        if np.array_equal(free.move, found[k][0].move):  # the plan already moves so: closing in changes nothing
            continue
        key = free.move.tobytes()
        if key not in levels:
            if spent():
                break
            levels[key] = _searches(problem.fixed_at(problem.slots_of(free.move)), "exact", [rows[k]], [rngs[k]],
                                    *budget, left(), node_limit)[0]
        sol, value = levels[key]
        if sol.feasible:  # always, with an off level
            found[k] = (replace(sol, optimal=False, gap=float("nan"), closed_in=True), value)  # optimal for the levels only
    return found


def _searches(problem: Problem, solver: str, rows: Sequence[int], rngs: Sequence[np.random.Generator],
              samples: int, iterations: int, neighbours: int, threads: int = 1,
              time_limit_s: float | None = 1.0, node_limit: int = 0) -> list[tuple[Solution, float]]:
    """:func:`own_searches` without closing in."""
    if solver != "grasp":
        sol = solve(problem, solver, list(rngs), time_limit_s=time_limit_s, node_limit=node_limit)
        return [(sol, sol.objective) for _ in rows]
    neigh, n_neigh = neighbour_lists(problem, neighbours)
    N = problem.n_agents
    cands = np.zeros((len(rows), N), dtype=np.int64)
    levels = np.zeros((len(rows), N), dtype=np.int64)

    values = np.empty(len(rows))
    p_s, w = problem.objective_tables()

    def search(k: int, stop: threading.Event) -> None:
        values[k] = grasp_search_chunked(
            rngs[k], int(rows[k]), (p_s, w), problem.gain, problem.levels_w, problem.delta_w,
            problem.at_least, problem.constraints, problem.n_cand, neigh, n_neigh,
            int(samples), int(iterations), cands[k], levels[k], stop,
        )

    run_searches(search, len(rows), threads)
    return [(to_solution(problem, cands[k], levels[k]), float(values[k])) for k in range(len(rows))]


def adopt(proposals: Sequence[Proposal], agent: int) -> Proposal | None:
    """The plan ``agent`` applies: the best announced plan that covers it (highest objective,
    ties to the lowest sender; NaN ranks lowest)."""
    covering = [p for p in proposals if agent in p.agents]
    if not covering:
        return None
    return min(covering, key=lambda p: (-(p.objective if np.isfinite(p.objective) else -np.inf), p.sender))
