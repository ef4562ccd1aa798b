"""The clairvoyant-chaser ceiling (ours): how often a team that knows the true position could
keep an agent close to the target, on the same truth trajectory.

Every step each agent moves at most ``max_step`` metres straight toward the target's true
position (ending on it when it is nearer), inside the area; while the target is absent it
hovers. The ceiling is the share of detectable steps at which the nearest agent is within ``d``
of the target. It is a reference, not a proof: a planner that anticipates the target could in
principle beat it. The proven bound (no agent that moves at most ``max_step`` per step is
nearer than ``|x_t - u_0| - t max_step``) is 1.0 on the Fig. 3 truths of seeds 1-20, so tells nothing there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trackjam.arguments import corners, flags, numeric, points, real

# At 8 m the detection probability at the top power level is p_D^max (R_0 / 8)^n_e
# = 0.95 (6/8)^2 = 0.53 (Eq. 9 with the paper's R_0 = 6 m, n_e = 2): a coin flip per agent.
NEAR = 8.0


@dataclass(frozen=True)
class Ceiling:
    share: float | None  # detectable steps with the nearest chaser within d, over detectable steps
    d: float  # [m]
    nearest: np.ndarray  # (T,) distance of the nearest chaser to the target [m]; NaN while absent
    positions: np.ndarray  # (T, N, 3) chasers' positions after each step's move [m]

    def summary(self) -> dict:
        """summary.json keys: ``ceiling_share`` (share of the detectable steps, None when there
        are none) and ``ceiling_d_m`` [m]."""
        return {"ceiling_share": self.share, "ceiling_d_m": self.d}


def chase(truth: np.ndarray, initial: np.ndarray, max_step: float, low, high) -> np.ndarray:
    """Positions (T, N, 3) of N agents that start at ``initial`` (N, 3) and, at each step t,
    move at most ``max_step`` [m] straight toward ``truth[t]`` (T, 3; rows with NaN: the target
    is absent and they hover), clipped to the box [low, high]: :func:`team_chase` with one target."""
    truth = numeric("truth", truth)
    if truth.ndim != 2 or truth.shape[1] != 3:
        raise ValueError(f"truth: need truth (T, 3), got {truth.shape}")
    return team_chase(truth.reshape(-1, 1, 3), initial, max_step, low, high)


def clairvoyant_ceiling(
    truth: np.ndarray,
    detectable: np.ndarray,
    initial: np.ndarray,
    max_step: float,
    low,
    high,
    d: float = NEAR,
) -> Ceiling:
    """The chaser's ceiling on one truth trajectory: ``truth`` (T, 3) true positions per step
    (NaN while absent), ``detectable`` (T,) the target is present and not occluded, ``initial``
    (N, 3) the agents' positions at t = 0, ``max_step`` the largest radial step [m]
    (``max(agents.radial_steps)``), ``low``, ``high`` the area's corners, ``d`` [m]:
    :func:`team_ceiling` with one target."""
    truth = numeric("truth", truth)
    detectable = np.asarray(detectable)
    if truth.ndim != 2 or truth.shape[1] != 3 or detectable.shape != truth.shape[:1]:
        raise ValueError(f"truth, detectable: need truth (T, 3) and detectable (T,), got {truth.shape} and {detectable.shape}")
    team = team_ceiling(truth.reshape(-1, 1, 3), detectable.reshape(-1, 1), initial, max_step, low, high, d)
    return Ceiling(share=team.shares[0], d=team.d, nearest=team.nearest[:, 0], positions=team.positions)


# Several targets (ours, issue 12): the same chasers, each step first shared out so that every
# present target has a chaser of its own.


def team_goals(u: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Which present target each of N agents at ``u`` (N, 3) chases this step: the (agent,
    target) pairs are taken in order of distance, each time the nearest pair whose agent is free
    and whose target has no chaser yet (ties by agent, then target index), until every present
    target has one or no agent is free; the other agents chase their nearest present target.
    ``targets`` (K, 3), NaN rows for absent targets. Returns (N,) target indices, -1 (hover)
    when no target is present. With one target every agent chases it, as :func:`chase`."""
    u = np.asarray(u, dtype=float).reshape(-1, 3)
    targets = np.asarray(targets, dtype=float).reshape(-1, 3)
    goals = np.full(len(u), -1, dtype=np.int64)
    live = np.flatnonzero(np.isfinite(targets).all(axis=1))
    if not len(live):
        return goals
    d = np.linalg.norm(u[:, None, :] - targets[None, live, :], axis=2)  # (N, L)
    taken = np.zeros(len(live), dtype=bool)
    for flat in np.argsort(d, axis=None, kind="stable"):
        j, i = divmod(int(flat), len(live))
        if goals[j] < 0 and not taken[i]:
            goals[j], taken[i] = live[i], True
            if taken.all():
                break
    free = goals < 0
    goals[free] = live[np.argmin(d[free], axis=1)]
    return goals


def team_chase(truth: np.ndarray, initial: np.ndarray, max_step: float, low, high) -> np.ndarray:
    """Positions (T, N, 3) of N agents that start at ``initial`` (N, 3) and at each step t move at
    most ``max_step`` [m] straight toward the true position of the target :func:`team_goals`
    gives them (``truth`` (T, K, 3), NaN rows while a target is absent; with none present they
    hover), clipped to the box [low, high]. :func:`chase` is its K = 1 case."""
    max_step = real("max_step", max_step, 0.0)
    truth = numeric("truth", truth)
    if truth.ndim != 3 or truth.shape[2] != 3:
        raise ValueError(f"truth: must have shape (T, K, 3), got {truth.shape}")
    u = points("initial", initial)
    if u.ndim > 2:
        raise ValueError(f"initial: expected rows of 3 entries (one agent: a vector), got shape {u.shape}")
    if u.size == 0:  # no chaser: the nearest one's distance was numpy's "zero-size array to reduction"
        raise ValueError(f"initial: the team needs at least one agent, got shape {u.shape}")
    u = np.array(u.reshape(-1, 3))
    low, high = corners(low, high, scalars=True)
    out = np.empty((len(truth), len(u), 3))
    for t, x in enumerate(truth):
        goals = team_goals(u, x)
        moving = goals >= 0
        gap = x[goals[moving]] - u[moving]
        dist = np.linalg.norm(gap, axis=1, keepdims=True)
        # moving the whole gap when it is shorter than a step lands exactly on the target
        frac = np.minimum(1.0, max_step / np.where(dist > 0, dist, 1.0))
        u[moving] = np.clip(u[moving] + frac * gap, low, high)
        out[t] = u
    return out


@dataclass(frozen=True)
class TeamCeiling:
    shares: list[float | None]  # per target: detectable steps with a chaser within d, over its detectable steps
    d: float  # [m]
    nearest: np.ndarray  # (T, K) distance of the nearest chaser to each target [m]; NaN while absent
    positions: np.ndarray  # (T, N, 3) chasers' positions after each step's move [m]
    total: float | None  # over all targets' detectable steps

    def summary(self) -> dict:
        """summary.json keys: ``ceiling_share`` (per target, None for one never detectable),
        ``ceiling_share_total`` (over all targets' detectable steps) and ``ceiling_d_m`` [m]."""
        return {"ceiling_share": self.shares, "ceiling_share_total": self.total, "ceiling_d_m": self.d}


def team_ceiling(truth: np.ndarray, detectable: np.ndarray, initial: np.ndarray, max_step: float, low, high,
                 d: float = NEAR) -> TeamCeiling:
    """The several-target ceiling: ``truth`` (T, K, 3) true positions (NaN while absent),
    ``detectable`` (T, K) present and not occluded; the rest as :func:`clairvoyant_ceiling`, which
    is its K = 1 case. A reference, not a bound: sharing the chasers out otherwise can do better
    for one target at another's cost."""
    d = real("d", d, 0.0, above=True)
    truth = numeric("truth", truth)
    detectable = np.asarray(detectable)
    if truth.ndim != 3 or truth.shape[2] != 3 or detectable.shape != truth.shape[:2]:
        raise ValueError(f"truth, detectable: need truth (T, K, 3) and detectable (T, K), got {truth.shape} and {detectable.shape}")
    given, detectable = detectable, flags(detectable)  # 0 / 1 was taken before the checks
    if detectable is None:
        raise ValueError(f"detectable: expected booleans (or 0 and 1), got {given.dtype}")
    if np.any(detectable & ~np.isfinite(truth).all(axis=2)):
        raise ValueError("truth, detectable: a detectable step has no true position")
    if np.any(np.isinf(truth)) or np.any(np.isnan(truth).any(axis=2) != np.isnan(truth).all(axis=2)):
        raise ValueError("truth: each row must be a finite position or all NaN (absent)")
    positions = team_chase(truth, initial, max_step, low, high)
    nearest = np.linalg.norm(positions[:, :, None, :] - truth[:, None, :, :], axis=3).min(axis=1)  # (T, K)
    close = detectable & (nearest <= d)
    n = detectable.sum(axis=0)
    shares = [int(c) / int(k) if k else None for c, k in zip(close.sum(axis=0), n)]
    total = int(close.sum()) / int(n.sum()) if n.sum() else None
    return TeamCeiling(shares=shares, d=float(d), nearest=nearest, positions=positions, total=total)
