"""The swarm engine's planning aims, and its search for lost targets (ours, issue 12).

An aim is where the team plans for one target: a confirmed team track (fused predicted
existence > 0.5) or, with ``control.fallback: search``, a *search aim*. The one-target engine's
search plans at the team's last track coasted by Eq. (1) while nobody believes in the target;
with several targets, the team remembers each team track's last confirmed fused state, and once
the track is no longer confirmed it plans at that state coasted to now, beside the confirmed
tracks, for at most ``SEARCH_STEPS`` steps after the last step it was confirmed. The assignment
then sends cones where the target has probably gone, and a detection there revives the track or
starts a new one. A search aim ends when its label is confirmed again, when a confirmed track (or
a more recently lost one) lies within the fusion gate of it (the target was found under another
label), or after those steps. Nothing is redrawn in the filters: under ``fusion.share: scans``
every filter already holds every scan.

``control.lead`` and ``control.horizon`` move each aim's planning point ahead along its velocity
(:func:`trackjam.control.pursuit.aim_ahead`), the fused predicted one or the coasted one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trackjam.control.pursuit import AimSettings, aim_ahead
from trackjam.estimation.lmb_fusion import GATE, mahalanobis2
from trackjam.world.motion import cv_coast

# Steps a lost track is searched for after the last step it was confirmed (ours). The coasted
# position's spread sqrt(trace(C_pos) / 3) grows as about k^1.5 sqrt(Sigma_v / 3): with the
# paper's Sigma_v = 0.5 it is 4.5 m after 5 steps and 6.0 m after 6 (from a track known exactly),
# past the 5 m radius that an 80 deg cone covers at R0 = 6 m from its apex, where p_D is highest;
# later, one cone at the coasted point covers little of where the target can be.
SEARCH_STEPS = 6


@dataclass(frozen=True)
class Aim:
    """One planning aim: the track it stands for, its state, and where the team plans for it."""

    label: str  # the team track's label (a search aim: the lost track's)
    mean: np.ndarray  # (6,) fused predicted state, or the last confirmed one coasted to now
    cov: np.ndarray  # (6, 6)
    point: np.ndarray  # (3,) x_bar_k, moved ahead by control.lead / control.horizon, inside the area [m]
    search: bool = False  # a search aim (a lost track), not a confirmed one


def plan_point(mean: np.ndarray, positions: np.ndarray, settings: AimSettings, low: np.ndarray,
               high: np.ndarray) -> np.ndarray:
    """x_bar_k of a state: its position, moved ahead along its velocity by :func:`aim_ahead`
    under the lead / horizon options, kept inside the area."""
    return np.clip(aim_ahead(np.asarray(mean[:3], float), np.asarray(mean[3:6], float), positions, settings), low, high)


class SearchMemory:
    """The team's last confirmed state of each track, and the search aims it gives."""

    def __init__(self, accel_var: float, steps: int = SEARCH_STEPS, gate: float = GATE) -> None:
        self.accel_var, self.steps, self.gate = accel_var, steps, gate
        self.last: dict[str, tuple[int, np.ndarray, np.ndarray]] = {}  # label -> (step, mean, cov)

    def remember(self, t: int, tracks: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
        """The confirmed team tracks after step ``t``'s fusion, as (label, mean, cov); a track
        lost longer than ``steps`` is forgotten."""
        for label, mean, cov in tracks:
            self.last[label] = (t, np.array(mean, dtype=float), np.array(cov, dtype=float))
        self.last = {k: v for k, v in self.last.items() if t + 1 - v[0] <= self.steps}

    def lost(self, t: int, confirmed: list[Aim]) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """At step ``t``'s planning: each remembered track not confirmed now, lost at most
        ``steps`` steps ago and not within the gate of a confirmed aim or of a more recently
        lost track, as (label, coasted mean, coasted cov), most recently confirmed first (ties
        by label)."""
        held = {a.label for a in confirmed}
        kept: list = list(confirmed)
        out = []
        for label, (seen, mean, cov) in sorted(self.last.items(), key=lambda kv: (-kv[1][0], kv[0])):
            age = t - seen
            if label in held or not 0 < age <= self.steps:
                continue
            m, P = cv_coast(mean, cov, self.accel_var, age)
            lost = Aim(label, m, P, m[:3], search=True)
            if all(mahalanobis2(lost, other) > self.gate for other in kept):
                kept.append(lost)
                out.append((label, m, P))
        return out
