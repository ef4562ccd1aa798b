"""Where an agent plans: Eq. (12)'s x_bar, or where a team that lost the target searches.

Three modes: ``track`` (some agent believes in the target: plan at x_bar), ``search`` (ours,
``control.fallback: search``: plan with the solver at the lost track coasted by Eq. (1)) and
``hover`` (the model document's fall-back: hover, keep the last aim, the highest levels Eq. (13)
allows). The team's rounds that use them are in :mod:`trackjam.simulation.team`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from trackjam.estimation.fusion import CONFIRM

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
    time_limit_s: float | None = 1.0  # exact's budget per search [s]
    node_limit: int = 0  # exact's budget per search in search nodes; 0: none
    belief_samples: int = 0  # control.plan_over: belief -> samples per agent; 0: plan at the point x_bar
    belief_spread: float | None = None  # control.belief_spread: the belief only while a heard spread exceeds it [m]
    belief_at_least: int | None = None  # control.belief_at_least: n on the steps planned over the belief; None: at_least
    close_in: float | None = None  # control.close_in: below this Xi the team closes in (ours); None: never
    greedy_aim: str = "team"  # control.greedy_aim: "own" -> greedy at each agent's own x_tilde^j (Eq. 11)

    @property
    def own_aims(self) -> bool:
        """Eq. (11) as printed: each agent plans alone at its own predicted mean and applies its own plan."""
        return self.solver == "greedy" and self.greedy_aim == "own"


def position_spread(cov: np.ndarray) -> float:
    """sqrt(trace(C_pos) / 3) [m]: the root-mean-square position spread per axis of a
    Gaussian (or particle) belief with covariance ``cov`` (position block first)."""
    return float(np.sqrt(np.trace(np.asarray(cov)[:3, :3]) / 3.0))


def wide_belief(predicted: Sequence, spread: float | None) -> bool:
    """``control.belief_spread``: plan over the belief this step, because some prediction
    received has a position spread above ``spread`` [m] (always, for None)."""
    return spread is None or any(est.cov is not None and position_spread(est.cov) > spread for est in predicted)


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
        if position_spread(est.cov) < COMPACT_SPREAD_M
    ]
    if compact:
        return np.clip(np.mean(compact, axis=0), low, high)
    return np.mean(aims, axis=0)


def belief_sample(X: np.ndarray, w: np.ndarray, k: int) -> np.ndarray:
    """``k`` positions that represent the particles ``X`` (n, >= 3) with weights ``w``: the
    particles at the weights' (i + 1/2)/k quantiles (deterministic systematic resampling, so
    the sample needs no random draw of its own)."""
    cdf = np.cumsum(w, dtype=float)
    idx = np.searchsorted(cdf, (np.arange(k) + 0.5) / k * cdf[-1])
    return np.array(X[np.minimum(idx, len(X) - 1), :3], dtype=float)


def pooled_belief(samples: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The planning sample of Eq. (12)'s belief average: every agent's sample, each agent's
    weight shared equally among its points (weights sum to 1)."""
    weights = np.concatenate([np.full(len(x), 1.0 / (len(x) * len(samples))) for x in samples])
    return np.vstack(samples), weights
