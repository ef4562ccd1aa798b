"""The trial draw of Section VI (Table I / Fig. 4 and Fig. 5) and the seeds of every trial.

A trial (Section VI, second paragraph): the target is spawned uniformly in the surveillance
area, the N pursuers uniformly in a ball of radius 20 m centred on it, and every antenna points
at the ball's centre. The model document (docs/model.md) fixes the rest:

- the target's velocity is uniform in +-v_b per axis (v_b = ``filter.birth_speed``), the same
  law as the filter's uniform birth (ours; the paper does not give the initial velocity);
- a pursuer drawn outside the area is redrawn (rejection), so the pursuers stay uniform in the
  part of the ball that lies in the area;
- the target exists from step 1 and is never occluded.

Seeds. The draw of trial k depends only on (experiment seed, k): every configuration of an
experiment starts trial k from the same positions (the paper's "same trials"). The simulation
seed of trial k is the same under every configuration too (``simulation_seed(seed, 0, k)``,
common random numbers): the truth's random walk is the same, and the noise, clutter and GRASP
streams start alike, so a comparison of configurations is paired on the truth, not only the
start (they drift apart once the configurations' agents see different things).
``simulation_seed`` still takes a configuration index, for callers that want independent streams.
Both come from ``np.random.SeedSequence(seed, spawn_key=...)``, so no result depends on the
number of workers, their order, or the backend.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BALL_RADIUS_M = 20.0  # radius of the ball the pursuers are spawned in (Section VI)
_DRAW, _SIMULATION = 0, 1  # first spawn-key entry: which stream


@dataclass(frozen=True)
class TrialDraw:
    """The initial condition of one trial."""

    index: int
    x0: np.ndarray  # target state [x, y, z, vx, vy, vz] at step 1 [m, m/s]
    u0: np.ndarray  # (N, 3) pursuer positions [m]

    @property
    def aim(self) -> np.ndarray:
        """Where every antenna points at t = 0: the ball's centre, the target's position."""
        return self.x0[:3]


def draw_rng(seed: int, k: int) -> np.random.Generator:
    """The random stream of trial k's draw (shared by all configurations)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_DRAW, k)))


def simulation_seed(seed: int, configuration: int, k: int) -> int:
    """Scenario seed of trial k under configuration ``configuration`` (a 63-bit integer)."""
    state = np.random.SeedSequence(seed, spawn_key=(_SIMULATION, configuration, k)).generate_state(1, np.uint64)
    return int(state[0] >> np.uint64(1))


def uniform_in_ball(rng: np.random.Generator, centre: np.ndarray, radius: float) -> np.ndarray:
    """One point uniform in the ball: an isotropic direction and a radius radius * U^(1/3)."""
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    return centre + radius * rng.uniform() ** (1.0 / 3.0) * d


def draw_trial(
    seed: int,
    k: int,
    low,
    high,
    n_agents: int,
    birth_speed: float,
    radius: float = BALL_RADIUS_M,
) -> TrialDraw:
    """Trial k of an experiment with seed ``seed``: target uniform in [low, high], velocity
    uniform in +-``birth_speed`` per axis, ``n_agents`` pursuers uniform in the ball of
    ``radius`` around the target and inside the area."""
    low = np.asarray(low, dtype=float)
    high = np.asarray(high, dtype=float)
    rng = draw_rng(seed, k)
    position = rng.uniform(low, high)
    velocity = rng.uniform(-birth_speed, birth_speed, size=3)
    u0 = np.empty((n_agents, 3))
    for j in range(n_agents):
        while True:
            u = uniform_in_ball(rng, position, radius)
            if np.all(u >= low) and np.all(u <= high):
                break
        u0[j] = u
    return TrialDraw(k, np.concatenate([position, velocity]), u0)


def trial_fields(draw: TrialDraw) -> dict:
    """Scenario keys (dotted) that place trial ``draw``: target, pursuers and initial aim."""
    return {
        "target.initial": [float(v) for v in draw.x0],
        "target.appears": 1,
        "target.disappears": None,
        "target.occlusions": [],
        "target.stochastic": None,
        "agents.initial": [[float(v) for v in u] for u in draw.u0],
        "agents.initial_aim": [float(v) for v in draw.aim],
    }
