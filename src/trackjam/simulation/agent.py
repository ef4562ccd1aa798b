"""A pursuer agent: its position, aim, filter, random streams, and what it remembers.

Everything that passes between agents is a :class:`Message`, carried by the team's exchange
(:mod:`trackjam.simulation.team`): positions and predicted estimates, then plans, then posterior
estimates for fusion (the paper's Fig. 2 and Section V-D).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trackjam.estimation.bernoulli import BernoulliFilter, Estimate
from trackjam.control.planning import belief_sample
from trackjam.estimation.fusion import CONFIRM
from trackjam.world.motion import cv_coast


@dataclass(frozen=True)
class Message:
    """What one agent tells the others at one round of step ``stamp``.

    ``prediction``: its position, aim, predicted estimate, and the team's lost track coasted to
    now as it remembers it (searching); ``plan``: the plan it proposes; ``posterior``: its
    updated estimate with the predicted existence it started from (for evidence fusion)."""

    sender: int
    kind: str  # "prediction" | "plan" | "posterior" | "scan"
    stamp: int
    position: np.ndarray | None = None
    estimate: Estimate | None = None
    aim: np.ndarray | None = None
    coasted: np.ndarray | None = None
    prior_existence: float | None = None
    belief: np.ndarray | None = None  # (S, 3) positions drawn from its predicted density (plan_over: belief)
    plan: object | None = None  # a trackjam.control.distributed.Proposal
    log_evidence: float | None = None  # posterior: log sum_i w_i L_i, its scan's evidence were the target visible
    visibility: float | None = None  # posterior: the predicted P(visible) it started from (hidden-target mode)
    scan: object | None = None  # scan: a trackjam.estimation.bernoulli.Scan (fusion.share: scans)
    tracks: list | None = None  # several targets: its predicted or updated tracks (TrackEstimate)
    informed: np.ndarray | None = None  # several targets, posterior: its cone reached each track this step


@dataclass
class Agent:
    """One pursuer: position u^j, last aim, filter, random streams, and the team's last track."""

    index: int
    position: np.ndarray
    aim: np.ndarray  # planning aim the antenna is steered to (kept under the fall-back)
    filter: BernoulliFilter
    sensor_rng: np.random.Generator  # measurement noise and clutter of this agent's radio
    plan_rng: np.random.Generator  # this agent's GRASP stream
    last_track: np.ndarray | None = None  # fused state [x, y, z, vx, vy, vz] when last tracked
    last_track_cov: np.ndarray | None = None
    steps_since_track: int = 0
    # the last coasted track (accel_var, steps, mean, cov): the next step's coast goes on from it,
    # one step, where coasting from the track each step made a long search quadratic in its
    # length (49 ms a step after 6,000 steps); the same products in the same order, so the same bits
    _coasted: tuple | None = field(default=None, repr=False, compare=False)

    def remember(self, existence: float, mean: np.ndarray | None, cov: np.ndarray | None) -> None:
        """Keep the team's last confirmed estimate, to search where the target has coasted to."""
        if existence > CONFIRM and mean is not None:
            self.last_track, self.last_track_cov = np.array(mean, dtype=float), np.array(cov, dtype=float)
            self.steps_since_track = 0
            self._coasted = None
        else:
            self.steps_since_track += 1

    def coasted_track(self, accel_var: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The last confirmed estimate predicted to now by Eq. (1)."""
        if self.last_track is None:
            return None
        k, x, P = 0, self.last_track, self.last_track_cov
        if self._coasted is not None and self._coasted[0] == accel_var and self._coasted[1] <= self.steps_since_track:
            _, k, x, P = self._coasted
        x, P = cv_coast(x, P, accel_var, self.steps_since_track - k)
        self._coasted = (accel_var, self.steps_since_track, x, P)
        return x.copy(), P.copy()  # the caller's to change; the kept ones stay as coasted

    @classmethod
    def create(cls, index: int, position, aim, bf: BernoulliFilter, cue: tuple[float, float, float] | None,
               sensor_seed: np.random.SeedSequence, plan_seed: np.random.SeedSequence,
               cue_velocity=None) -> "Agent":
        """An agent at ``position`` aimed at ``aim``; ``cue`` = (e_0, position std, velocity std)
        starts its filter from a Gaussian around the aim (ours, ``filter.cue``), at rest, or with
        mean velocity ``cue_velocity`` v: then around [aim - v, v], the state whose prediction
        by Eq. (1) puts the mean at the aim at step 1."""
        if cue is not None:
            existence, pos_std, vel_std = cue
            v = np.zeros(3) if cue_velocity is None else np.asarray(cue_velocity, dtype=float)
            mean = np.concatenate([np.asarray(aim, dtype=float) - v, v])
            cov = np.diag([pos_std**2] * 3 + [vel_std**2] * 3)
            bf.reset_to(existence, mean, cov)
        return cls(
            index=index,
            position=np.asarray(position, dtype=float),
            aim=np.asarray(aim, dtype=float),
            filter=bf,
            sensor_rng=np.random.default_rng(sensor_seed),
            plan_rng=np.random.default_rng(plan_seed),
        )

    def predict(self, t: int, accel_var: float, belief_samples: int = 0) -> Message:
        """Section V-A's prediction, announced with position, aim, the coasted lost track and,
        planning over the belief, a sample of the predicted particles."""
        coasted = self.coasted_track(accel_var)
        estimate = self.filter.predict()
        belief = None
        if belief_samples:
            f = self.filter
            X, log_w = f.survivors()  # once: each of f.particles and f.log_w builds both
            w = np.exp(log_w - log_w.max())
            nu = f.visible  # filter.visibility.per_particle: where the target is and can be seen
            if nu is not None and w @ nu > 0.0:
                w = w * nu
            belief = belief_sample(X, w, belief_samples)
        return Message(self.index, "prediction", t, position=self.position.copy(), estimate=estimate,
                       aim=self.aim.copy(), coasted=None if coasted is None else coasted[0], belief=belief)

    def update(self, t: int, Z: np.ndarray, point: np.ndarray, level_w: float, prior_existence: float,
               others=()) -> Message:
        f = self.filter
        est = f.update(Z, self.position, point, level_w, others)
        return Message(self.index, "posterior", t, position=self.position.copy(), estimate=est,
                       prior_existence=prior_existence, log_evidence=f.log_evidence,
                       visibility=None if f.visibility is None else f.nu_pred)
