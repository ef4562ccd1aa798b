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


@dataclass(frozen=True)
class Message:
    """What one agent tells the others at one stage of a step."""

    sender: int
    kind: str  # "prediction" | "posterior"
    position: np.ndarray
    estimate: Estimate


@dataclass
class Exchange:
    """All-to-all broadcast: every agent receives every message of a round, its own included."""

    rounds: int = 0
    sent: int = 0

    def all_to_all(self, messages: list[Message]) -> list[Message]:
        self.rounds += 1
        self.sent += len(messages) * max(len(messages) - 1, 0)
        return sorted(messages, key=lambda m: m.sender)


@dataclass
class Agent:
    """One pursuer: position u^j, last aim, transmit level, filter and random streams."""

    index: int
    position: np.ndarray
    aim: np.ndarray  # planning aim the antenna is steered to (kept under the fall-back)
    filter: BernoulliFilter
    sensor_rng: np.random.Generator  # measurement noise and clutter of this agent's radio
    plan_rng: np.random.Generator  # this agent's GRASP stream
    level_index: int = 0
    pending: list = field(default_factory=list)

    @classmethod
    def create(cls, index: int, scenario: Scenario, position, aim, seeds: list[np.random.SeedSequence]) -> "Agent":
        filter_seed, sensor_seed, plan_seed = seeds
        return cls(
            index=index,
            position=np.asarray(position, dtype=float),
            aim=np.asarray(aim, dtype=float),
            filter=BernoulliFilter(scenario, np.random.default_rng(filter_seed)),
            sensor_rng=np.random.default_rng(sensor_seed),
            plan_rng=np.random.default_rng(plan_seed),
        )

    def predict(self) -> Message:
        return Message(self.index, "prediction", self.position.copy(), self.filter.predict())

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
