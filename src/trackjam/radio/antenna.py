"""Conic sensing profile, detection probability (Eq. 9), received power (Eq. 10) and the
interference between agents (the left side of Eq. 13).

One function, :func:`cone_gain`, carries the geometry: it is ``g(eta)`` for a point inside the
cone and 0 outside. Detection probability and received power are that gain scaled by the level,
so detection, jamming of the target and interference between agents can never disagree.

All functions broadcast over leading dimensions: one candidate or thousands at once.
``kernel_cone_gain`` is the compiled scalar twin used inside numba loops; the tests hold it to
the numpy version.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from trackjam.arguments import amounts, points, real, together, vector



@dataclass(frozen=True)
class AntennaModel:
    """The antenna parameters in the units the maths uses (radians, watts)."""

    height: float  # h_a [m], along the axis
    half_angle: float  # theta_a / 2 [rad]
    r0: float  # R_0 [m]
    n_e: float  # path-loss exponent
    p_d_max: float  # p_D^max
    levels_w: np.ndarray  # L in watts, increasing; 0 is "off"
    delta_w: float  # interference tolerance delta [W]

    def __post_init__(self) -> None:
        # the configuration's bounds (trackjam.config); built by hand, an opening of 200 deg gave
        # a negative range, levels of zero a NaN p_D, and a kernel read past a short level list
        real("height", self.height, 0.0, above=True)
        real("half_angle", self.half_angle, 0.0, math.radians(85.0), above=True)
        real("r0", self.r0, 0.0, above=True)
        real("n_e", self.n_e, 0.0, 10.0, above=True)
        real("p_d_max", self.p_d_max, 0.0, 1.0)
        levels = vector("levels_w", self.levels_w, 2, at_least=True)
        if levels[0] != 0.0 or np.any(np.diff(levels) <= 0.0):
            raise ValueError(f"levels_w: must start at 0 (off) and increase, got {levels.tolist()!r:.60}")
        real("delta_w", self.delta_w, 0.0, above=True)

    @property
    def l_max(self) -> float:
        return float(self.levels_w[-1])

    @property
    def tan_half(self) -> float:
        return float(np.tan(self.half_angle))

    @property
    def max_range(self) -> float:
        """Farthest point of the cone from its apex: the rim, h_a / cos(theta_a / 2)."""
        return self.height / float(np.cos(self.half_angle))



def axis_of(apex: np.ndarray, aim: np.ndarray) -> np.ndarray:
    """Unit vector from ``apex`` toward ``aim``; +z where the two coincide (ours)."""
    d = np.asarray(aim, dtype=float) - np.asarray(apex, dtype=float)
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    up = np.zeros_like(d)
    up[..., 2] = 1.0
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 1e-12, d / np.where(n > 1e-12, n, 1.0), up)


def inside_cone(p, apex, aim, height: float, half_angle: float) -> np.ndarray:
    """Whether ``p`` lies in the right circular cone with apex ``apex`` pointing at ``aim``.

    Inside when ``0 <= s <= h_a`` and ``|p - apex - s*axis| <= s*tan(theta_a/2)`` with
    ``s = (p - apex) . axis`` (docs/model.md, antenna). The apex itself is inside.
    """
    p = np.asarray(p, dtype=float)
    apex = np.asarray(apex, dtype=float)
    axis = axis_of(apex, aim)
    d = p - apex
    s = np.sum(d * axis, axis=-1)
    radial = np.linalg.norm(d - s[..., None] * axis, axis=-1)
    tol = 1e-9
    return (s >= -tol) & (s <= height + tol) & (radial <= s * np.tan(half_angle) + tol)


def path_gain(eta, r0: float, n_e: float) -> np.ndarray:
    """g(eta) = 1 for eta <= R_0, (R_0 / eta)^n_e beyond: continuous at R_0."""
    eta = np.asarray(eta, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(eta <= r0, 1.0, (r0 / np.maximum(eta, r0)) ** n_e)


def cone_gain(p, apex, aim, ant: AntennaModel) -> np.ndarray:
    """g(|p - apex|) when ``p`` is inside the cone aimed at ``aim``, else 0."""
    p = np.asarray(p, dtype=float)
    apex = np.asarray(apex, dtype=float)
    eta = np.linalg.norm(p - apex, axis=-1)
    inside = inside_cone(p, apex, aim, ant.height, ant.half_angle)
    return np.where(inside, path_gain(eta, ant.r0, ant.n_e), 0.0)


def _antenna(ant) -> AntennaModel:
    if not isinstance(ant, AntennaModel):
        raise TypeError(f"ant: expected an AntennaModel, got {type(ant).__name__}")
    return ant


def _beam(x, u, aim, level_w, ant, up_to_l_max: bool = False):
    """The arguments of Eqs. (9)-(10) checked (the README's pieces used alone): positions
    ``x``, ``u`` and ``aim`` finite with 3 coordinates on the last axis, levels finite in
    [0, inf) (in [0, l_max] with ``up_to_l_max``), all of shapes that broadcast together.
    Checking costs microseconds; it changes no value."""
    _antenna(ant)
    x, u, aim = points("x", x), points("u", u), points("aim", aim)
    level_w = amounts("level_w", level_w, 0.0, ant.l_max if up_to_l_max else math.inf)
    together(dict(x=x.shape, u=u.shape, aim=aim.shape, level_w=level_w.shape),
             x=x.shape[:-1], u=u.shape[:-1], aim=aim.shape[:-1], level_w=level_w.shape)
    return x, u, aim, level_w


def detection_probability(x, u, aim, level_w, ant: AntennaModel) -> np.ndarray:
    """Eq. (9): p_D(x, u, l) = (l / l_max) p_D^max g(eta) inside the cone, 0 outside; a level
    in [0, l_max]."""
    x, u, aim, level_w = _beam(x, u, aim, level_w, ant, up_to_l_max=True)
    return level_w / ant.l_max * ant.p_d_max * cone_gain(x, u, aim, ant)


def received_power(x, u, aim, level_w, ant: AntennaModel) -> np.ndarray:
    """Eq. (10): power received at ``x`` from a sender at ``u`` aimed at ``aim`` [W]; any level >= 0."""
    x, u, aim, level_w = _beam(x, u, aim, level_w, ant)
    return level_w * cone_gain(x, u, aim, ant)


def interference_matrix(positions, aims, levels_w, ant: AntennaModel) -> np.ndarray:
    """``R[i, j]``: power agent ``i`` receives from agent ``j``'s cone (zero diagonal) [W].

    Agent ``i`` is jammed when ``R[i].sum() >= delta`` (docs/model.md).
    """
    _antenna(ant)
    u = points("positions", positions, ndim=2)
    n = u.shape[0]
    a = points("aims", aims, ndim=2)
    lv = amounts("levels_w", levels_w)
    if a.shape != u.shape or lv.shape != (n,):
        raise ValueError(f"positions, aims, levels_w: expected shapes ({n}, 3), ({n}, 3) and ({n},), "
                         f"got {u.shape}, {a.shape} and {lv.shape}")
    # receivers on axis 0, senders on axis 1
    R = lv[None, :] * cone_gain(u[:, None, :], u[None, :, :], a[None, :, :], ant)
    R[np.arange(n), np.arange(n)] = 0.0
    return R


@njit(cache=True)
def kernel_cone_gain(px, py, pz, ux, uy, uz, ax, ay, az, height, tan_half, r0, n_e):
    """Scalar compiled twin of :func:`cone_gain`; (ax, ay, az) is the unit axis."""
    dx = px - ux
    dy = py - uy
    dz = pz - uz
    s = dx * ax + dy * ay + dz * az
    tol = 1e-9
    if s < -tol or s > height + tol:
        return 0.0
    rx = dx - s * ax
    ry = dy - s * ay
    rz = dz - s * az
    if np.sqrt(rx * rx + ry * ry + rz * rz) > s * tan_half + tol:
        return 0.0
    eta = np.sqrt(dx * dx + dy * dy + dz * dz)
    if eta <= r0:
        return 1.0
    return (r0 / eta) ** n_e
