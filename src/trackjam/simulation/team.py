"""The team: its agents and the exchange of messages between them (the paper's Fig. 2).

A step's three rounds of messages: positions and predicted estimates (from which each agent
forms x_bar), then posterior estimates, which each agent fuses (covariance intersection) and
feeds back into its own filter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trackjam.control.planning import planning_aim, search_point
from trackjam.estimation.fusion import FusedEstimate, fuse
from trackjam.simulation.agent import Agent, Message


@dataclass(frozen=True)
class TeamSettings:
    """The fusion and fall-back options the team's rounds read."""

    existence_rule: str  # fusion.existence: "mean" | "evidence"
    feedback: bool  # fusion.feedback
    searching: bool  # control.fallback == "search"
    accel_var: float  # the filters' Sigma_v scale, used to coast a lost track


class Exchange:
    """All-to-all broadcast: every agent receives every message of a round, its own included,
    in sender order."""

    def broadcast(self, messages: list[Message]) -> list[list[Message]]:
        """One inbox per agent."""
        ordered = sorted(messages, key=lambda m: m.sender)
        return [ordered for _ in messages]


class Team:
    def __init__(self, agents: list[Agent], settings: TeamSettings, exchange: Exchange | None = None) -> None:
        self.agents = agents
        self.settings = settings
        self.exchange = exchange or Exchange()
        self.predicted: list[list[Message]] = [[] for _ in agents]  # each agent's inbox

    @property
    def positions(self) -> np.ndarray:
        return np.array([a.position for a in self.agents])

    @property
    def aims(self) -> np.ndarray:
        return np.array([a.aim for a in self.agents])

    def predict(self) -> None:
        """Round 1: every agent predicts (Section V-A) and broadcasts position and prediction."""
        self.predicted = self.exchange.broadcast([a.predict() for a in self.agents])

    def planning_aims(self) -> list[np.ndarray | None]:
        """Each agent's x_bar (Eq. 12) from the predictions it received."""
        return [planning_aim([m.estimate for m in inbox]) for inbox in self.predicted]

    def search_points(self, low: np.ndarray, high: np.ndarray) -> list[np.ndarray]:
        """Where each agent would search: the team's lost track coasted, as the agent remembers it."""
        q = self.settings.accel_var
        coasted = [c[0] for c in (a.coasted_track(q) for a in self.agents) if c is not None]
        return [
            search_point(coasted, [m.estimate for m in inbox], self.aims, low, high)
            for inbox in self.predicted
        ]

    def steer(self, aim: np.ndarray) -> None:
        for a in self.agents:
            a.aim = np.array(aim, dtype=float)

    def move(self, displacements: np.ndarray) -> None:
        for a, d in zip(self.agents, displacements):
            a.position = a.position + d

    def update(self, scans: list[np.ndarray], points: np.ndarray, level_w: np.ndarray) -> list[Message]:
        """Each agent updates its filter on its own scan (Section V-A)."""
        return [a.update(Z, points[j], float(level_w[j])) for j, (a, Z) in enumerate(zip(self.agents, scans))]

    def fuse(self, posteriors: list[Message]) -> FusedEstimate:
        """Round 3: posteriors are broadcast; each agent fuses what it received, remembers the
        team's track and, with ``fusion.feedback``, reseeds its filter from the fused estimate
        (a searching team from its lost track coasted). Returns agent 0's fusion, the team's
        report."""
        s = self.settings
        inboxes = self.exchange.broadcast(posteriors)
        fused_by = []
        for a, inbox, predicted in zip(self.agents, inboxes, self.predicted):
            fused = fuse([m.estimate for m in inbox], predicted=[m.estimate.existence for m in predicted],
                         rule=s.existence_rule)
            fused_by.append(fused)
            a.remember(fused.existence, fused.mean, fused.cov)
            if not s.feedback:
                continue
            if fused.mean is None and s.searching and a.last_track is not None:
                mean, cov = a.coasted_track(s.accel_var)
                a.filter.reset_to(fused.existence, mean, cov)
            else:
                a.filter.reset_to(fused.existence, fused.mean, fused.cov)
        return fused_by[0]
