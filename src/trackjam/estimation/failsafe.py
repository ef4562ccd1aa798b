"""The fail-safe a team expects of a target it jams (``filter.response``, ours, beyond the paper).

A commercial drone whose control link is jammed runs a fail-safe: it lands, hovers or flies home
(``target.response`` simulates one). A filter that keeps predicting Eq. (1)'s constant velocity
then aims every cone where the target would have flown on: the target that the team has just
downed leaves the cones within a step and is lost (the swarm experiment held 86 % of its downed
targets at the step they were downed and 49 % one step later).

With ``filter.response`` the filter knows the fail-safe it may trigger, and it knows the team's
own transmissions (every agent adopts a plan that holds every teammate's move, level and aim). Per
track (the one Bernoulli component, or each LMB track):

- after each update, the *jammed share* is the posterior weight of the particles at which the
  team's cones deliver at least the response's threshold (Eq. (10) summed over the senders);
- the track counts a jammed step when that share is at least one half, and is *downed* after
  ``steps`` consecutive jammed steps, as the truth target is (:class:`trackjam.world.target.TruthTarget`);
- from the next prediction on, every particle of a downed track moves as the fail-safe moves the
  truth (``land``: straight down to the ground at ``speed`` m/step, then still; ``hover``: still;
  ``return``: towards ``home`` at ``speed`` m/step, then still) instead of by Eq. (1), with Eq. (1)'s
  position noise (Gamma's position part, std sqrt(accel_var) / 2 per axis) so the cloud keeps its
  spread;
- a track the team no longer confirms (existence <= 0.5 after an update) forgets the count and
  the fail-safe: its particles fly on by Eq. (1) from the velocities they have.

``filter.response: null`` (the default) is the paper's constant-velocity filter, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numba import njit

from trackjam.radio.antenna import AntennaModel, axis_of, cone_gain, kernel_cone_gain

JAMMED_SHARE = 0.5  # a step counts as jammed when at least this share of the track's weight is jammed


@dataclass(frozen=True)
class FailSafe:
    """What the filter expects a jammed target to do (the truth's :class:`Response` fields)."""

    threshold_w: float  # received power that jams it [W]
    steps: int  # consecutive jammed steps before the fail-safe starts
    action: str  # "land" | "hover" | "return"
    speed: float  # [m/step] while landing or returning
    home: np.ndarray  # (3,) where "return" flies to [m]
    ground: float  # z of the area's floor, where "land" ends [m]
    hedge: float = 0.0  # share of a downed track's particles that keep flying by Eq. (1)


@dataclass(frozen=True)
class JamWatch:
    """One track's count of consecutive jammed steps and whether its fail-safe has started."""

    run: int = 0
    downed: bool = False
    fresh: bool = False  # downed (or reseeded) since the last prediction: the hedge is drawn at the next one

    def after(self, jammed: bool, confirmed: bool, steps: int) -> "JamWatch":
        """The watch after one update: reset when the track is not confirmed; else count the
        step (or restart the count) and start the fail-safe at ``steps`` in a row. A downed
        track stays downed while it is confirmed."""
        if not confirmed:
            return JamWatch()
        if self.downed:
            return self
        run = self.run + 1 if jammed else 0
        return JamWatch(run, run >= steps, run >= steps)


def received_at(X: np.ndarray, positions: np.ndarray, points: np.ndarray, levels_w: np.ndarray,
                ant: AntennaModel) -> np.ndarray:
    """(n,) power the team's cones deliver at each particle position ``X[:, :3]`` [W]: Eq. (10)
    summed over the senders at ``positions`` aimed at ``points`` transmitting ``levels_w``."""
    x = np.asarray(X, dtype=float)[:, None, :3]
    u = np.asarray(positions, dtype=float)[None, :, :]
    a = np.asarray(points, dtype=float)[None, :, :]
    lv = np.asarray(levels_w, dtype=float)[None, :]
    if u.shape[1] == 0:
        return np.zeros(len(X))
    return (lv * cone_gain(x, u, a, ant)).sum(axis=1)


@njit(cache=True)
def kernel_jammed_share(X, w, u, axes, levels_w, height, tan_half, r0, n_e, threshold_w):
    """Compiled :func:`jammed_share`: the weight ``w`` of the rows of ``X`` at which the senders
    at ``u`` (unit cone axes ``axes``, levels ``levels_w``) deliver at least ``threshold_w``
    (:func:`received_at` is its plain-numpy reference)."""
    total = 0.0
    for i in range(X.shape[0]):
        p = 0.0
        for j in range(u.shape[0]):
            if levels_w[j] > 0.0:
                p += levels_w[j] * kernel_cone_gain(X[i, 0], X[i, 1], X[i, 2], u[j, 0], u[j, 1], u[j, 2],
                                                    axes[j, 0], axes[j, 1], axes[j, 2], height, tan_half, r0, n_e)
        if p >= threshold_w:
            total += w[i]
    return total


def jammed_share(X: np.ndarray, w: np.ndarray, positions: np.ndarray, points: np.ndarray, levels_w: np.ndarray,
                 ant: AntennaModel, threshold_w: float) -> float:
    """The weight (``w``, normalised) of the particles that receive at least ``threshold_w``
    from the team's cones (compiled; :func:`received_at` gives the powers themselves)."""
    u = np.ascontiguousarray(positions, dtype=np.float64).reshape(-1, 3)
    if len(X) == 0 or len(u) == 0:
        return 0.0
    axes = np.ascontiguousarray(axis_of(u, np.asarray(points, dtype=np.float64).reshape(-1, 3)))
    return float(kernel_jammed_share(np.ascontiguousarray(X, dtype=np.float64), np.ascontiguousarray(w, dtype=np.float64),
                                     u, axes, np.ascontiguousarray(levels_w, dtype=np.float64).reshape(-1),
                                     ant.height, math.tan(ant.half_angle), ant.r0, ant.n_e, float(threshold_w)))


def watched(watch: JamWatch, confirmed: bool, particles: Callable[[], tuple[np.ndarray, np.ndarray]],
            positions: np.ndarray, points: np.ndarray, levels_w: np.ndarray, ant: AntennaModel,
            fs: FailSafe) -> JamWatch:
    """A track's watch after an update: the step is jammed when the team's cones deliver the
    threshold to at least :data:`JAMMED_SHARE` of its weight. ``particles()`` gives its particles
    and normalised log-weights; it is called only for a confirmed track (an unconfirmed one
    starts over)."""
    jammed = False
    if confirmed:
        X, log_w = particles()
        jammed = jammed_share(X, np.exp(log_w), positions, points, levels_w, ant, fs.threshold_w) >= JAMMED_SHARE
    return watch.after(jammed, confirmed, fs.steps)


def fail_safe_move(X: np.ndarray, noise: np.ndarray, fs: FailSafe, accel_var: float) -> None:
    """One step of the fail-safe for every particle, in place: the truth's move
    (:meth:`trackjam.world.target.TruthTarget._fail_safe`, whose one-state scalar code stays the
    reference this vectorised twin is tested against, to 1e-12) plus the position noise
    ``noise`` (n, 3) standard normals times sqrt(accel_var) / 2; the velocity becomes the step."""
    if len(X) == 0:
        return
    if fs.action == "hover":
        step = np.zeros((len(X), 3))
    else:
        goal = np.broadcast_to(fs.home, (len(X), 3)).copy() if fs.action == "return" else X[:, :3].copy()
        if fs.action == "land":
            goal[:, 2] = fs.ground
        d = goal - X[:, :3]
        dist = np.linalg.norm(d, axis=1, keepdims=True)
        scale = np.where(dist <= fs.speed, 1.0, fs.speed / np.maximum(dist, 1e-300))
        step = d * scale
    X[:, :3] += step + 0.5 * np.sqrt(accel_var) * noise
    X[:, 3:6] = step
    if fs.action == "land":
        np.maximum(X[:, 2], fs.ground, out=X[:, 2])  # the noise does not take it underground


def following(X: np.ndarray, fs: FailSafe) -> np.ndarray:
    """(n,) which particles already move as the fail-safe, read from the velocity that
    :func:`fail_safe_move` left them: ``land`` vx = vy = 0 exactly, ``hover`` v = 0 exactly,
    ``return`` v = 0 or a step of at most ``speed`` pointing home (within 8 deg, the position
    noise aside). A particle flying by Eq. (1) has no exact zero."""
    v = X[:, 3:6]
    if fs.action == "land":
        return (v[:, 0] == 0.0) & (v[:, 1] == 0.0)
    still = np.all(v == 0.0, axis=1)
    if fs.action == "hover":
        return still
    d = fs.home - (X[:, :3] - v)  # home from where the step started, up to the noise
    nv, nd = np.linalg.norm(v, axis=1), np.linalg.norm(d, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        aligned = np.sum(v * d, axis=1) >= 0.99 * nv * nd
    return still | ((nv <= fs.speed * (1 + 1e-9)) & aligned)


def move_downed(X: np.ndarray, rng: np.random.Generator, fs: FailSafe, accel_var: float, cv_move, fresh: bool) -> None:
    """One prediction of a downed track's particles ``X``, in place. Without a hedge every
    particle moves as the fail-safe. With ``fs.hedge`` = h: at the prediction after the downing
    (or after a reseed from a Gaussian, ``fresh``) each particle takes the fail-safe with
    probability 1 - h and keeps flying by Eq. (1) (``cv_move``) otherwise; after that each keeps
    its branch (:func:`following`), so the detections choose between the two."""
    if fs.hedge == 0.0:
        fail_safe_move(X, rng.standard_normal((len(X), 3)), fs, accel_var)
        return
    mask = rng.uniform(size=len(X)) >= fs.hedge if fresh else following(X, fs)
    for idx, fail in ((np.flatnonzero(mask), True), (np.flatnonzero(~mask), False)):
        if len(idx) == 0:
            continue
        Y = np.ascontiguousarray(X[idx])
        if fail:
            fail_safe_move(Y, rng.standard_normal((len(Y), 3)), fs, accel_var)
        else:
            cv_move(Y)
        X[idx] = Y
