"""A PettingZoo environment for learning controllers of the pursuer team (needs the ``env``
extra: ``pip install ".[env]"`` from the checkout)."""

from __future__ import annotations

from typing import TYPE_CHECKING

try:
    import gymnasium  # noqa: F401
    import pettingzoo  # noqa: F401
except ImportError as err:  # pragma: no cover - depends on the installation
    raise ImportError(f"trackjam.env needs the env extra: pip install \".[env]\" from the trackjam checkout ({err})") from None

from trackjam.env.observation import observation_layout, state_layout
from trackjam.env.parallel import Planned, TrackjamParallelEnv
from trackjam.env.policies import random_policy, rollout, solver_policy
from trackjam.env.swarm import SwarmParallelEnv
from trackjam.env.swarm_observation import swarm_observation_layout, swarm_state_layout
from trackjam.env.wrappers import NormalizedObservations, normalized
from trackjam.simulation.build import is_scenario

if TYPE_CHECKING:  # the scenario is only handed on: simulation/build.py reads it
    from trackjam.simulation.build import Scenario

__all__ = ["NormalizedObservations", "Planned", "SwarmParallelEnv", "TrackjamParallelEnv", "normalized",
           "observation_layout", "parallel_env", "random_policy", "rollout", "solver_policy", "state_layout",
           "swarm_observation_layout", "swarm_state_layout"]


def parallel_env(scenario: Scenario, jam_penalty: float = 1.0, render_mode: str | None = None,
                 replay_path: str = "replay.html", track_slots: int | None = None,
                 render_size: tuple[int, int] | None = None) -> TrackjamParallelEnv:
    """The team as a PettingZoo ``ParallelEnv`` on ``scenario`` (a :class:`Scenario`, e.g. from
    :func:`trackjam.load_scenario`); ``jam_penalty`` is lambda of the reward. A scenario with
    several ``targets`` gives a :class:`SwarmParallelEnv` (the swarm engine), whose agents
    observe and may serve ``track_slots`` of their view's tracks (default 4; the team's view
    without ``comms`` faults, each agent's own under them); one target gives a
    :class:`TrackjamParallelEnv`, which has no slots. ``render_size`` = (width, height) makes
    ``render()`` under ``render_mode="rgb_array"`` return a frame of that many pixels (the
    figure scaled to fit, its aspect kept) instead of the whole figure."""
    is_scenario(scenario)
    if len(scenario.target_list) > 1:
        return SwarmParallelEnv(scenario, jam_penalty=jam_penalty, render_mode=render_mode, replay_path=replay_path,
                                track_slots=track_slots, render_size=render_size)
    if track_slots is not None:
        raise ValueError(f"track_slots: {track_slots!r:.40} given for a scenario with one target; the slots are "
                         "the several-target environment's (an action there names the track it serves)")
    return TrackjamParallelEnv(scenario, jam_penalty=jam_penalty, render_mode=render_mode, replay_path=replay_path,
                               render_size=render_size)
