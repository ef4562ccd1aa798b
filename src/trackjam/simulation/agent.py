"""A pursuer agent and the message exchange between agents.

Each agent owns its filter, its random streams and its view of the others; everything that
passes between agents goes through :class:`Exchange`, so the distributed structure of the paper
(Fig. 2 and Section V-D) is visible: agents share positions and predicted estimates, then plans,
then posterior estimates for fusion.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trackjam.config import Scenario
from trackjam.estimation.bernoulli import BernoulliFilter, Estimate
from trackjam.world.target import cv_matrices


@dataclass(frozen=True)
class Message:
    """What one agent tells the others at one stage of a step."""

    sender: int
    kind: str  # "prediction" | "posterior"
    position: np.ndarray
    estimate: Estimate


class Exchange:
    """All-to-all broadcast: every agent receives every message of a round, its own included."""

    def all_to_all(self, messages: list[Message]) -> list[Message]:
        return sorted(messages, key=lambda m: m.sender)


@dataclass
class Agent:
    """One pursuer: position u^j, last aim, filter, random streams and view of the team."""

    index: int
    position: np.ndarray
    aim: np.ndarray  # planning aim the antenna is steered to (kept under the fall-back)
    filter: BernoulliFilter
    sensor_rng: np.random.Generator  # measurement noise and clutter of this agent's radio
    plan_rng: np.random.Generator  # this agent's GRASP stream
    view: list = field(default_factory=list)  # the last messages received from the team
    last_track: np.ndarray | None = None  # fused state [x, y, z, vx, vy, vz] when last tracked
    last_track_cov: np.ndarray | None = None
    steps_since_track: int = 0

    def remember(self, existence: float, mean: np.ndarray | None, cov: np.ndarray | None) -> None:
        """Keep the team's last confirmed estimate, to search where the target has coasted to."""
        if existence > 0.5 and mean is not None:
            self.last_track, self.last_track_cov = np.array(mean, dtype=float), np.array(cov, dtype=float)
            self.steps_since_track = 0
        else:
            self.steps_since_track += 1

    def coasted_track(self, accel_var: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The last confirmed estimate predicted to now by Eq. (1): Phi^k x, Phi P Phi' + Q per step."""
        if self.last_track is None:
            return None
        Phi, Gamma = cv_matrices(1.0)
        Q = accel_var * Gamma @ Gamma.T
        x, P = self.last_track, self.last_track_cov
        for _ in range(self.steps_since_track):
            x, P = Phi @ x, Phi @ P @ Phi.T + Q
        return x, P

    @classmethod
    def create(cls, index: int, scenario: Scenario, position, aim, seeds: list[np.random.SeedSequence]) -> "Agent":
        filter_seed, sensor_seed, plan_seed = seeds
        bf = BernoulliFilter(scenario, np.random.default_rng(filter_seed))
        cue = scenario.filter.cue
        if cue is not None:
            mean = np.concatenate([np.asarray(aim, dtype=float), np.zeros(3)])
            cov = np.diag([cue.position_std**2] * 3 + [cue.velocity_std**2] * 3)
            bf.reset_to(cue.existence, mean, cov)
        return cls(
            index=index,
            position=np.asarray(position, dtype=float),
            aim=np.asarray(aim, dtype=float),
            filter=bf,
            sensor_rng=np.random.default_rng(sensor_seed),
            plan_rng=np.random.default_rng(plan_seed),
        )

    def predict(self) -> Message:
        return Message(self.index, "prediction", self.position.copy(), self.filter.predict())

    def receive(self, messages: list[Message]) -> None:
        """This agent's view of the team: what the last exchange brought it."""
        self.view = messages

    def update(self, Z: np.ndarray, point: np.ndarray, level_w: float) -> Message:
        est = self.filter.update(Z, self.position, point, level_w)
        return Message(self.index, "posterior", self.position.copy(), est)


def planning_aim(predictions: list[Message]) -> np.ndarray | None:
    """x_bar of Eq. (12): mean of the predicted positions of the agents whose predicted
    existence e_{t|t-1} exceeds 0.5; None when no agent believes in the target."""
    believers = [m.estimate.mean[:3] for m in predictions if m.estimate.existence > 0.5]
    if not believers:
        return None
    return np.mean(believers, axis=0)
