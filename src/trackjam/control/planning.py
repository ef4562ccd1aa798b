"""One step's planning, as each agent does it: where to aim (Eq. 12's x_bar, or where a team
that lost the target searches), then the joint moves and levels (Eqs. 11-13) or the fall-back.

Three modes: ``track`` (some agent believes in the target: plan at x_bar), ``search`` (ours,
``control.fallback: search``: plan with the solver at the lost track coasted by Eq. (1)) and
``hover`` (MODEL.md's fall-back: hover, keep the last aim, the highest levels Eq. (13) allows).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from trackjam.control.fallback import fallback_levels
from trackjam.control.problem import build_problem
from trackjam.control.solve import solve
from trackjam.estimation.fusion import CONFIRM
from trackjam.radio.antenna import AntennaModel

COMPACT_SPREAD_M = 10.0  # a predicted density this tight (position std) is worth searching at


@dataclass(frozen=True)
class PlanSettings:
    """The control options a step's planning reads (Sections V-B to V-D and ours)."""

    solver: str
    at_least: int
    constraints: bool
    samples: int
    iterations: int
    neighbours: int
    threads: int
    fallback: str  # "hover" | "search"


@dataclass(frozen=True)
class Plan:
    """What the team decided for one step."""

    mode: str  # "track" | "search" | "hover" | "external"
    aim: np.ndarray | None  # x_bar (track), the search point (search); None: each keeps its aim
    moves: np.ndarray  # (N,) displacement indices
    levels: np.ndarray  # (N,) level indices
    objective: float  # Xi^N_n of the plan at x_bar; NaN unless tracking
    solve_s: float  # wall time of the decision


def planning_aim(predicted: Sequence) -> np.ndarray | None:
    """x_bar of Eq. (12): mean of the predicted positions of the agents whose predicted
    existence e_{t|t-1} exceeds 0.5; None when no agent believes in the target.
    ``predicted`` holds the agents' predicted :class:`Estimate` s."""
    believers = [est.mean[:3] for est in predicted if est.existence > CONFIRM]
    if not believers:
        return None
    return np.mean(believers, axis=0)


def search_point(coasted: Sequence[np.ndarray], predicted: Sequence, aims: np.ndarray,
                 low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Where a team that tracks nothing looks (ours, ``control.fallback: search``): its last
    confirmed track coasted by Eq. (1) (``coasted``: one state per agent that had one); if it
    never tracked, the mean predicted position of the agents whose predicted density is compact
    (position standard deviation under COMPACT_SPREAD_M); else the mean of the current aims."""
    if len(coasted):
        return np.clip(np.mean([c[:3] for c in coasted], axis=0), low, high)
    compact = [
        est.mean[:3] for est in predicted
        if np.sqrt(np.trace(est.cov[:3, :3]) / 3) < COMPACT_SPREAD_M
    ]
    if compact:
        return np.clip(np.mean(compact, axis=0), low, high)
    return np.mean(aims, axis=0)


def plan_step(positions: np.ndarray, x_bar: np.ndarray | None, search_at: np.ndarray | None,
              aims: np.ndarray, displacements: np.ndarray, ant: AntennaModel, low: np.ndarray,
              high: np.ndarray, settings: PlanSettings, rngs: list[np.random.Generator]) -> Plan:
    """The step's decision: solve Eqs. (12)-(13) at x_bar when tracking, at ``search_at`` when
    searching, or fall back to hovering at the highest admissible levels."""
    t0 = time.perf_counter()
    if x_bar is None and settings.fallback != "search":
        levels = fallback_levels(positions, aims, ant, settings.constraints)
        moves = np.zeros(len(positions), dtype=np.int64)
        return Plan("hover", None, moves, levels, np.nan, time.perf_counter() - t0)
    aim = x_bar if x_bar is not None else search_at
    problem = build_problem(positions, aim, displacements, ant, low, high, settings.at_least,
                            settings.constraints)
    sol = solve(problem, settings.solver, rngs, samples=settings.samples,
                iterations=settings.iterations, neighbours=settings.neighbours,
                threads=settings.threads)
    mode = "track" if x_bar is not None else "search"
    objective = sol.objective if x_bar is not None else np.nan
    return Plan(mode, aim, sol.move, sol.level, objective, time.perf_counter() - t0)
