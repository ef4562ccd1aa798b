"""What an agent of the learning environment observes, as one flat float32 vector.

Layout for agent j of a team of N (``observation_layout`` names every entry):

- ``own.x/y/z``: its position u_t after the step's move [m], clipped to the area (the engine
  admits a position up to 1e-9 m past a wall: float rounding of a move along it);
- ``own.est.x/y/z/vx/vy/vz``, ``own.est.e``: the estimate its filter holds after the step (with
  ``fusion.feedback``, the fused estimate fed back) [m, m/s] and its existence probability;
- for each teammate k != j, in index order, what j received from k in the step's first round
  (the paper's Fig. 2): ``mateK.received`` (1 if a message arrived this step, else 0 and the
  rest of the block is 0), ``mateK.x/y/z`` (k's position as announced, before the move) [m],
  ``mateK.pred.x/y/z/vx/vy/vz`` and ``mateK.pred.e``, k's predicted estimate e_{t|t-1};
- ``time``: t / steps, the share of the episode elapsed.

N agents observe 11 N numbers each.

The global state (``state_layout``; ``TrackjamParallelEnv.state()``, for a centralised critic: no
agent observes it) holds, for every agent k in index order, ``agentK.x/y/z`` (its position [m],
clipped to the area as above), ``agentK.est.x/y/z/vx/vy/vz`` and ``agentK.est.e`` (its filter's
estimate and existence), then the truth: ``target.x/y/z/vx/vy/vz`` [m, m/s] (0 while the target
does not exist), ``target.exists``, ``target.detectable`` (it exists and is not occluded), and
``time``: 10 N + 9 numbers.
"""

from __future__ import annotations

import numpy as np

MAX_AGENTS = 64  # the configuration's bound on the team (config/limits.py; tests/test_config_hostile.py holds them equal)
STATE = ("x", "y", "z", "vx", "vy", "vz")
MATE_BLOCK = 11  # received flag, position (3), predicted state (6), predicted existence


def observation_layout(n_agents: int) -> list[str]:
    """The name of every entry of an agent's observation (the same for every agent), for a team
    of ``n_agents`` in [1, MAX_AGENTS], the bound a scenario's team is held to (it gave a layout
    for 0 and -1 agents, and built 10^5 agents' names without a word)."""
    if (isinstance(n_agents, (bool, np.bool_)) or not isinstance(n_agents, (int, np.integer))
            or not 1 <= n_agents <= MAX_AGENTS):
        raise ValueError(f"n_agents: expected a whole number in [1, {MAX_AGENTS}] (the team's size), "
                         f"got {n_agents!r:.60}")
    names = ["own.x", "own.y", "own.z"] + [f"own.est.{s}" for s in STATE] + ["own.est.e"]
    for k in range(1, n_agents):
        names += [f"mate{k}.received", f"mate{k}.x", f"mate{k}.y", f"mate{k}.z"]
        names += [f"mate{k}.pred.{s}" for s in STATE] + [f"mate{k}.pred.e"]
    return names + ["time"]


def observation_bounds(n_agents: int, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds of the layout: the agent's own position lies in the area (an inadmissible move
    is replaced by hovering); probabilities, flags and time in [0, 1]; estimates are unbounded
    (a filter's mean may stray past a wall with ``filter.walls: none``)."""
    names = observation_layout(n_agents)
    lo = np.full(len(names), -np.inf, dtype=np.float32)
    hi = np.full(len(names), np.inf, dtype=np.float32)
    lo[:3], hi[:3] = low, high
    for i, name in enumerate(names):
        if name.endswith((".e", ".received")) or name == "time":
            lo[i], hi[i] = 0.0, 1.0
    return lo, hi


def state_layout(n_agents: int) -> list[str]:
    """The name of every entry of the global state, for a team of ``n_agents`` in [1, MAX_AGENTS]."""
    observation_layout(n_agents)  # the same check of n_agents
    names = []
    for k in range(n_agents):
        names += [f"agent{k}.x", f"agent{k}.y", f"agent{k}.z"] + [f"agent{k}.est.{s}" for s in STATE]
        names.append(f"agent{k}.est.e")
    return names + [f"target.{s}" for s in STATE] + ["target.exists", "target.detectable", "time"]


def state_bounds(n_agents: int, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds of the global state: the agents' positions in the area; existence, flags and
    time in [0, 1]; estimates unbounded (a filter's mean may stray past a wall with
    ``filter.walls: none``) and the truth too (the engine keeps a target up to 1e-9 m past a
    wall; one that flies out under ``walls: leave`` no longer exists, and its entries are 0)."""
    names = state_layout(n_agents)
    lo = np.full(len(names), -np.inf, dtype=np.float32)
    hi = np.full(len(names), np.inf, dtype=np.float32)
    for k in range(n_agents):
        lo[10 * k : 10 * k + 3], hi[10 * k : 10 * k + 3] = low, high
    for i, name in enumerate(names):
        if name.endswith((".e", ".exists", ".detectable")) or name == "time":
            lo[i], hi[i] = 0.0, 1.0
    return lo, hi


def global_state(positions: np.ndarray, estimates: list, truth_state: np.ndarray | None, exists: bool,
                 detectable: bool, fraction: float) -> np.ndarray:
    """The global state of :func:`state_layout`: ``positions`` (N, 3) clipped to the area,
    ``estimates`` each agent's filter Estimate, the true target's state (None while it does
    not exist)."""
    n = len(positions)
    out = np.zeros(10 * n + 9, dtype=np.float32)
    for k, (u, est) in enumerate(zip(positions, estimates)):
        out[10 * k : 10 * k + 3] = u
        out[10 * k + 3 : 10 * k + 9] = est.mean
        out[10 * k + 9] = est.existence
    if truth_state is not None:
        out[10 * n : 10 * n + 6] = truth_state
    out[10 * n + 6] = float(exists)
    out[10 * n + 7] = float(detectable)
    out[-1] = fraction
    return out


def observe(j: int, position: np.ndarray, own, received: list, n_agents: int, fraction: float) -> np.ndarray:
    """Agent j's observation. ``own`` is the Estimate its filter holds; ``received`` the
    messages (sender, position, estimate) of the step's prediction round in j's inbox."""
    obs = np.zeros(MATE_BLOCK * n_agents, dtype=np.float32)
    obs[:3] = position
    obs[3:9] = own.mean
    obs[9] = own.existence
    by_sender = {m.sender: m for m in received}
    for slot, k in enumerate(k for k in range(n_agents) if k != j):
        m = by_sender.get(k)
        if m is None:
            continue
        base = 10 + slot * MATE_BLOCK
        obs[base] = 1.0
        obs[base + 1 : base + 4] = m.position
        obs[base + 4 : base + 10] = m.estimate.mean
        obs[base + 10] = m.estimate.existence
    obs[-1] = fraction
    return obs
