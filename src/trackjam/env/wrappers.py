"""Observations and the global state scaled to [-1, 1]: :func:`normalized` wraps an environment
of :func:`trackjam.env.parallel_env` (one target or several) without touching its episode.

Every entry x is mapped by one affine map, y = (x - centre) / half-width, whose centre and
half-width come from the entry's range:

- an entry the environment's Box bounds (the agents' own and teammates' positions by the area,
  existence, flags, shares, a teammate's age and time in [0, 1], the swarm state's level indices
  in [0, L - 1]) is
  mapped from its Box bounds onto [-1, 1], and the wrapped Box says [-1, 1];
- an entry the environment leaves unbounded (a filter's or track's estimate, the true target in
  the state) has no bound to map from: a position (``.x/.y/.z``) is scaled by the area as the
  bounded positions are, a velocity (``.vx/.vy/.vz``) by ``speed`` (default: the pursuers' top
  speed, the longest displacement of a step, dT = 1 s), and the wrapped Box keeps it unbounded.
  Such an entry lies in [-1, 1] while the estimate is inside the area and no faster than
  ``speed`` along the axis, and past it otherwise: it is scaled, not clipped, so that the
  wrapped observation maps back to the environment's exactly (up to float32 rounding). An
  unbounded entry that is neither is refused at construction (none is today).

A 0 of the environment (an empty slot, a teammate not heard from) is therefore not 0 once
wrapped: a flag reads -1, a position of 0 m (one target: an unheard teammate's) the area's low
wall's value.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from pettingzoo.utils.wrappers import BaseParallelWrapper

from trackjam.errors import bounded_repr
from trackjam.env.observation import observation_layout, state_layout
from trackjam.env.parallel import TrackjamParallelEnv
from trackjam.env.swarm import SwarmParallelEnv
from trackjam.env.swarm_observation import swarm_observation_layout, swarm_state_layout

MAX_SPEED = 1e3  # m/s: the configuration's bound on every speed (config/limits.py, mirrored: env reads none)


def affine(names: list[str], box: spaces.Box, low: np.ndarray, high: np.ndarray,
           speed: float) -> tuple[np.ndarray, np.ndarray, spaces.Box]:
    """The centre and half-width of every entry of ``box`` (named by ``names``), and the Box of
    the scaled entries (module docstring)."""
    lo, hi = box.low.astype(float), box.high.astype(float)
    centre, half = np.zeros(len(names)), np.ones(len(names))
    out_lo, out_hi = np.full(len(names), -1.0), np.ones(len(names))
    for i, name in enumerate(names):
        if np.isfinite(lo[i]) and np.isfinite(hi[i]):
            centre[i], half[i] = (lo[i] + hi[i]) / 2, (hi[i] - lo[i]) / 2
            if half[i] == 0:  # a single value (one level): it maps to 0
                half[i] = 1.0
            continue
        axis = name.rsplit(".", 1)[-1]
        if axis in ("x", "y", "z"):
            k = "xyz".index(axis)
            centre[i], half[i] = (low[k] + high[k]) / 2, (high[k] - low[k]) / 2
        elif axis in ("vx", "vy", "vz"):
            centre[i], half[i] = 0.0, speed
        else:  # pragma: no cover - every unbounded entry of today's layouts is a position or a velocity
            raise ValueError(f"normalized: the entry {name} is unbounded and neither a position nor a velocity: "
                             "no range to scale it by")
        out_lo[i], out_hi[i] = -np.inf, np.inf
    return centre, half, spaces.Box(out_lo.astype(np.float32), out_hi.astype(np.float32), dtype=np.float32)


class NormalizedObservations(BaseParallelWrapper):
    """A trackjam environment whose observations and global state are scaled to [-1, 1] (module
    docstring); actions, rewards, terminations and infos pass unchanged, and so does every other
    attribute (``sim``, ``agents``, ``target_ids``, ...)."""

    def __init__(self, env: TrackjamParallelEnv, speed: float | None = None) -> None:
        if isinstance(env, NormalizedObservations):
            raise ValueError("normalized: env is already normalized; wrapping it again would scale its "
                             "unbounded entries twice")
        if not isinstance(env, TrackjamParallelEnv):
            raise TypeError(f"normalized: env must be an environment of trackjam.env.parallel_env, got "
                            f"{type(env).__name__} {bounded_repr(env, 40)}")
        super().__init__(env)
        n = len(env.possible_agents)
        if isinstance(env, SwarmParallelEnv):
            c = env.sim.c.base
            obs_names = swarm_observation_layout(n, env.track_slots)
            state_names = swarm_state_layout(n, len(env.target_ids))
        else:
            c = env.sim.c
            obs_names, state_names = observation_layout(n), state_layout(n)
        top = float(np.linalg.norm(c.displacements, axis=1).max())  # m per step of dT = 1 s
        if speed is None:
            speed = top if top > 0 else 1.0
        elif (isinstance(speed, (bool, np.bool_)) or not isinstance(speed, (int, float, np.integer, np.floating))
              or not 0 < speed <= MAX_SPEED):
            raise ValueError(f"normalized: speed must be a number of m/s in (0, {MAX_SPEED:g}], got "
                             f"{bounded_repr(speed, 40)}")
        self.speed = float(speed)
        self._obs_centre, self._obs_half, box = affine(obs_names, env.observation_space(env.possible_agents[0]),
                                                       c.low, c.high, self.speed)
        self.observation_spaces = {a: spaces.Box(box.low, box.high, dtype=np.float32) for a in env.possible_agents}
        self._state_centre, self._state_half, self.state_space = affine(state_names, env.state_space, c.low,
                                                                        c.high, self.speed)

    # -- the maps ------------------------------------------------------------------------

    @staticmethod
    def _scaled(x, centre: np.ndarray, half: np.ndarray, what: str) -> np.ndarray:
        x = np.asarray(x)
        if x.shape != centre.shape:
            raise ValueError(f"{what}: expected a vector of {len(centre)} entries, got shape {x.shape}")
        return ((x.astype(float) - centre) / half).astype(np.float32)

    @staticmethod
    def _unscaled(y, centre: np.ndarray, half: np.ndarray, what: str) -> np.ndarray:
        y = np.asarray(y)
        if y.shape != centre.shape:
            raise ValueError(f"{what}: expected a vector of {len(centre)} entries, got shape {y.shape}")
        return (y.astype(float) * half + centre).astype(np.float32)

    def normalize_observation(self, x) -> np.ndarray:
        """An observation of the environment, scaled as this wrapper gives it."""
        return self._scaled(x, self._obs_centre, self._obs_half, "normalize_observation")

    def unnormalize_observation(self, y) -> np.ndarray:
        """A wrapped observation back in the environment's units (m, m/s, ...)."""
        return self._unscaled(y, self._obs_centre, self._obs_half, "unnormalize_observation")

    def normalize_state(self, x) -> np.ndarray:
        """A global state of the environment, scaled as :meth:`state` gives it."""
        return self._scaled(x, self._state_centre, self._state_half, "normalize_state")

    def unnormalize_state(self, y) -> np.ndarray:
        """A wrapped global state back in the environment's units."""
        return self._unscaled(y, self._state_centre, self._state_half, "unnormalize_state")

    # -- the API -------------------------------------------------------------------------

    def observation_space(self, agent: str) -> spaces.Box:
        self.env.observation_space(agent)  # the environment's check of the name
        return self.observation_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        obs, infos = self.env.reset(seed=seed, options=options)
        return {a: self.normalize_observation(o) for a, o in obs.items()}, infos

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        obs, rewards, terminations, truncations, infos = self.env.step(actions)
        return ({a: self.normalize_observation(o) for a, o in obs.items()}, rewards, terminations, truncations,
                infos)

    def state(self) -> np.ndarray:
        return self.normalize_state(self.env.state())

    def __repr__(self) -> str:
        return f"NormalizedObservations({type(self.env).__name__}, speed={self.speed:g})"


def normalized(env: TrackjamParallelEnv, speed: float | None = None) -> NormalizedObservations:
    """``env`` (from :func:`trackjam.env.parallel_env`) with every observation entry and the
    global state scaled to [-1, 1] from the spaces' bounds (positions by the area, velocities by
    ``speed`` m/s, default the pursuers' top speed); the same episodes, seed for seed."""
    return NormalizedObservations(env, speed=speed)
