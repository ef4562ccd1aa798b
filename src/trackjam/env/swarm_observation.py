"""What an agent of the several-target environment observes, and the global state, as flat
float32 vectors (:class:`trackjam.env.swarm.SwarmParallelEnv`).

Layout for agent j of a team of N with M track slots (``swarm_observation_layout`` names every
entry):

- ``own.x/y/z``: its position after the step's move [m], clipped to the area;
- per slot S = 1..M, the confirmed tracks of the agent's own fused view after the step (fused
  existence > 0.5, the tracks the swarm engine plans at), most likely first (ties by label),
  the rest of the slots empty: ``trackS.occupied`` (1, or 0 and the block's other entries 0),
  the fused state ``trackS.x/y/z/vx/vy/vz`` [m, m/s] and existence ``trackS.e``,
  ``trackS.served`` (1 if this agent's antenna served the track on the step just run),
  ``trackS.servers`` (the share of the team the agent knows served it: with every message
  delivered, the team's share; under the ``comms`` faults no message says what a teammate
  served, so its own antenna only, ``served`` / N). Without faults every agent's view is the
  team's; under them, its own (``SwarmSimulation.views[j]``);
- per teammate k != j, in index order, what the agent last heard of it: ``mateK.received`` (1 if
  it heard k this step), ``mateK.x/y/z`` (k's position [m], clipped to the area) and
  ``mateK.age`` ((t - the step it was heard) / steps, 0 when heard this step). With every
  message delivered: k's position after the move, received 1, age 0. Under the ``comms``
  faults: the position k announced in its last prediction that reached the agent
  (``SwarmSimulation.known[j][k]``), before that step's move; never heard, the briefing: k's
  start, age t / steps. After ``reset``, the briefing: every teammate's start, received 1, age 0;
- ``time``: t / steps.

N agents and M slots: 3 + 10 M + 5 (N - 1) + 1 numbers.

The global state (``swarm_state_layout``; no agent observes it): ``agentK.x/y/z`` and
``agentK.level`` (the index of the level it sent at, 0 before the first step) for every agent;
then per target I = 0..K-1, in the scenario's order: ``targetI.x/y/z/vx/vy/vz`` (0 while it
does not exist), ``targetI.exists``, ``targetI.detectable``, ``targetI.held`` (a reported track
lies within the gate of it, as the run's ``targets`` log says); then ``time``.
"""

from __future__ import annotations

import numpy as np

from trackjam.env.observation import MAX_AGENTS, STATE, observation_layout

MAX_SLOTS = 64  # track slots an environment may have
SLOT_BLOCK = 10  # occupied, state (6), existence, served, servers
MATE_BLOCK = 5  # received, position (3), age
TARGET_BLOCK = 9  # state (6), exists, detectable, held


def checked_slots(track_slots) -> int:
    """``track_slots``, a whole number in [1, MAX_SLOTS]."""
    if (isinstance(track_slots, (bool, np.bool_)) or not isinstance(track_slots, (int, np.integer))
            or not 1 <= track_slots <= MAX_SLOTS):
        raise ValueError(f"track_slots: expected a whole number in [1, {MAX_SLOTS}], got {track_slots!r:.60}")
    return int(track_slots)


def swarm_observation_layout(n_agents: int, track_slots: int) -> list[str]:
    """The name of every entry of an agent's observation, for a team of ``n_agents`` in [1,
    MAX_AGENTS] and ``track_slots`` in [1, MAX_SLOTS]."""
    observation_layout(n_agents)  # the same check of n_agents
    names = ["own.x", "own.y", "own.z"]
    for s in range(1, checked_slots(track_slots) + 1):
        names += [f"track{s}.occupied"] + [f"track{s}.{v}" for v in STATE]
        names += [f"track{s}.e", f"track{s}.served", f"track{s}.servers"]
    for k in range(1, n_agents):
        names += [f"mate{k}.received", f"mate{k}.x", f"mate{k}.y", f"mate{k}.z", f"mate{k}.age"]
    return names + ["time"]


def swarm_observation_bounds(n_agents: int, track_slots: int, low: np.ndarray,
                             high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds of the layout: positions in the area; flags, existence, shares, ages and time
    in [0, 1]; the tracks' states unbounded (a filter's mean may stray past a wall)."""
    names = swarm_observation_layout(n_agents, track_slots)
    lo = np.full(len(names), -np.inf, dtype=np.float32)
    hi = np.full(len(names), np.inf, dtype=np.float32)
    for i, name in enumerate(names):
        if name.startswith(("own.", "mate")) and name.endswith((".x", ".y", ".z")):
            k = "xyz".index(name[-1])
            lo[i], hi[i] = low[k], high[k]
        elif name.endswith((".occupied", ".e", ".served", ".servers", ".received", ".age")) or name == "time":
            lo[i], hi[i] = 0.0, 1.0
    return lo, hi


def swarm_state_layout(n_agents: int, n_targets: int) -> list[str]:
    """The name of every entry of the global state, for ``n_agents`` in [1, MAX_AGENTS] and
    ``n_targets`` in [1, MAX_AGENTS]."""
    observation_layout(n_agents)
    if (isinstance(n_targets, (bool, np.bool_)) or not isinstance(n_targets, (int, np.integer))
            or not 1 <= n_targets <= MAX_AGENTS):
        raise ValueError(f"n_targets: expected a whole number in [1, {MAX_AGENTS}], got {n_targets!r:.60}")
    names = []
    for k in range(n_agents):
        names += [f"agent{k}.x", f"agent{k}.y", f"agent{k}.z", f"agent{k}.level"]
    for i in range(n_targets):
        names += [f"target{i}.{v}" for v in STATE] + [f"target{i}.exists", f"target{i}.detectable", f"target{i}.held"]
    return names + ["time"]


def swarm_state_bounds(n_agents: int, n_targets: int, n_levels: int, low: np.ndarray,
                       high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds of the global state: the agents' positions in the area, their levels in
    [0, L - 1], the flags and time in [0, 1], the truth unbounded (the engine keeps a target up
    to 1e-9 m past a wall)."""
    names = swarm_state_layout(n_agents, n_targets)
    lo = np.full(len(names), -np.inf, dtype=np.float32)
    hi = np.full(len(names), np.inf, dtype=np.float32)
    for i, name in enumerate(names):
        if name.startswith("agent"):
            if name.endswith(".level"):
                lo[i], hi[i] = 0.0, n_levels - 1
            else:
                k = "xyz".index(name[-1])
                lo[i], hi[i] = low[k], high[k]
        elif name.endswith((".exists", ".detectable", ".held")) or name == "time":
            lo[i], hi[i] = 0.0, 1.0
    return lo, hi


def swarm_observe(position: np.ndarray, tracks: list[tuple[np.ndarray, float, bool, float]],
                  mates: list[tuple[np.ndarray, bool, float]], track_slots: int, fraction: float) -> np.ndarray:
    """One agent's observation. ``position`` (3,) its own, clipped to the area; ``tracks`` the
    occupied slots in order, each (state (6,), existence, served by the agent, share of the team
    serving it); ``mates`` per teammate in index order (position (3,) clipped to the area,
    received this step, age as a share of the episode)."""
    obs = np.zeros(3 + SLOT_BLOCK * track_slots + MATE_BLOCK * len(mates) + 1, dtype=np.float32)
    obs[:3] = position
    for s, (mean, e, served, servers) in enumerate(tracks[:track_slots]):
        base = 3 + SLOT_BLOCK * s
        obs[base] = 1.0
        obs[base + 1 : base + 7] = mean
        obs[base + 7 : base + 10] = (e, float(served), servers)
    base = 3 + SLOT_BLOCK * track_slots
    for slot, (u, received, age) in enumerate(mates):
        b = base + MATE_BLOCK * slot
        obs[b] = float(received)
        obs[b + 1 : b + 4] = u
        obs[b + 4] = age
    obs[-1] = fraction
    return obs


def swarm_state(positions: np.ndarray, levels: np.ndarray, states: np.ndarray, exists: np.ndarray,
                detectable: np.ndarray, held: np.ndarray, fraction: float) -> np.ndarray:
    """The global state of :func:`swarm_state_layout`: ``positions`` (N, 3) clipped to the area,
    ``levels`` (N,) indices, ``states`` (K, 6) the truth (NaN rows while absent)."""
    n, k = len(positions), len(states)
    out = np.zeros(4 * n + TARGET_BLOCK * k + 1, dtype=np.float32)
    for j, (u, level) in enumerate(zip(positions, levels)):
        out[4 * j : 4 * j + 3] = u
        out[4 * j + 3] = level
    for i in range(k):
        base = 4 * n + TARGET_BLOCK * i
        if exists[i]:
            out[base : base + 6] = states[i]
        out[base + 6 : base + 9] = (float(exists[i]), float(detectable[i]), float(held[i]))
    out[-1] = fraction
    return out
