"""The Bernoulli particle filter of one agent (Section V-A, after Ristic et al. 2013).

Prediction (printed in Section V-A):

    e_{t|t-1} = p_b (1 - e_{t-1}) + p_s e_{t-1}
    s_{t|t-1}(x) = q_{t|t-1}(x) + p_s e_{t-1} ∫ pi(x | x') s_{t-1}(x') dx' / e_{t|t-1},
    q_{t|t-1}(x) = p_b (1 - e_{t-1}) b_t(x) / e_{t|t-1}

so the predicted particle set is the survivors moved by Eq. (1) with weight
``p_s e_{t-1} / e_{t|t-1}`` in all, and ``n_b`` birth particles with ``p_b (1 - e_{t-1}) /
e_{t|t-1}`` in all. Update:

    q_t = ∫ p_D s_{t|t-1} - sum_{y in Y_t} ∫ p_D g_t(y | x, u_t) s_{t|t-1} dx / (lambda_c p_c(y))
    e_t = (1 - q_t) e_{t|t-1} / (1 - e_{t|t-1} q_t)
    s_t(x) = [(1 - p_D) + p_D sum_y g_t(y | x, u_t) / (lambda_c p_c(y))] s_{t|t-1}(x) / (1 - q_t)

with ``p_D = p_D(x, u_t, l_t)`` of Eq. (9) per particle and ``g_t = N(y; h(x, u_t), Sigma_w)``
(angle residuals wrapped). With particle weights ``w_i`` and the bracket ``L_i``,
``1 - q_t = sum_i w_i L_i``; the update runs in the log domain and an empty scan is a real
update (every factor is ``1 - p_D``, so a miss lowers the existence).

Birth density b_t (``filter.birth``, see :mod:`trackjam.estimation.birth`): ``uniform`` (the
paper), ``measurement`` (ours: around the previous scan's measurements) or ``mixed`` (ours:
``filter.birth_mix`` of the measurement-driven and the rest uniform).

How the particles are spent (ours; the densities are the printed ones): the uniform birth is
importance-sampled around the current scan's measurements, and the part of s_t born at the last
step (the *young* component, born at t-1 and seen once) is kept apart, as a weighted set with its
mass, for one step: when the next scan comes in it is drawn again by the two-scan proposal, whose
velocities join the two scans. The rest of s_t is resampled to ``n`` particles.

The point estimate (``filter.mode``, ours): the paper reports the mean and covariance of all of
s_t. A belief that has spread out over where a lost target may be can be split between a mode
that the last detections support and a wide remainder; its mean then lies between the two, and
its spread says nothing is located. With ``filter.mode`` = (r, m) the posterior estimate is the
mean and covariance of the particles within r metres of the densest point of s_t
(:func:`mode_moments`), when they hold at least m of its weight; otherwise the paper's moments.
The predicted estimate (the planning aim) is the paper's.

The filter starts with ``e_0 = 0`` (nothing is known) and its particles drawn from the uniform
birth density, so that ``reset_to`` or a later birth has something to work with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np
from scipy.special import expit

from trackjam.arguments import corners, real, vector, whole
from trackjam.estimation.failsafe import FailSafe, JamWatch, move_downed, watched
from trackjam.estimation.birth import (
    PROPOSAL_FLOOR,
    PROPOSAL_INFLATE,
    YOUNG_FLOOR,
    YOUNG_INFLATE,
    Gaussians,
    UniformBirth,
    draw_measurement_birth,
    draw_uniform_birth,
    measurement_covariances,
    redraw_young,
)
from trackjam.estimation.kernels import (
    MODE_MAX_CELLS,
    MODE_MAX_INDEX,
    MODE_SHIFTS,
    kernel_cv_predict,
    kernel_logsumexp,
    kernel_masked_moments,
    kernel_mode_cluster,
    kernel_reflect,
    kernel_split_sums,
    kernel_systematic_indices,
    kernel_take_rows,
    kernel_update_factors,
    kernel_weighted_moments,
)
from trackjam.radio.antenna import AntennaModel, axis_of
from trackjam.radio.measurement import clutter_density
from trackjam.world.motion import cv_matrices

DT = 1.0  # dT [s]
PHI, _GAMMA = cv_matrices(DT)
GG = _GAMMA @ _GAMMA.T  # Eq. (1)'s process noise is accel_var * Gamma Gamma^T
# resampling (ours): the fewest slots the particles a scan supported get, a share of the
# survivors' slots but at most a few birth counts
RESERVE_SHARE = 0.4
RESERVE_CAP = 3
NEVER = 1 << 30  # scans since a scan supported a particle's line: never


@dataclass(frozen=True)
class Scan:
    """What the update of one step needs from the radio: measurements ``Z`` (m, 3) taken from
    ``u`` with the antenna's unit ``axis`` and ``p_d_scale = (l / l_max) p_D^max``; ``lag`` > 0
    marks a teammate's scan of ``lag`` steps ago that arrived late (``comms.stale: coast``)."""

    Z: np.ndarray
    u: np.ndarray
    axis: np.ndarray
    p_d_scale: float
    lag: int = 0

    @classmethod
    def of(cls, Z, u, aim, level_w: float, ant: AntennaModel) -> "Scan":
        u = np.asarray(u, dtype=float)
        return cls(np.asarray(Z, dtype=float).reshape(-1, 3), u, axis_of(u, np.asarray(aim, dtype=float)),
                   max(float(level_w), 0.0) / ant.l_max * ant.p_d_max)

    def late(self, lag: int) -> "Scan":
        """This scan arriving ``lag`` steps after it was taken."""
        return replace(self, lag=int(lag))

    def log_factors(self, X: np.ndarray, ant: AntennaModel, noise_std, log_lambda_c: float) -> np.ndarray:
        """log L_i of every particle (the bracket of the update). A late scan is weighed at each
        particle retrodicted by Eq. (1) without its noise, x - lag dT v (ours: the particles
        are at the current step, the scan was taken ``lag`` steps before; walls are ignored)."""
        if self.lag:
            X = np.array(X, dtype=float)
            X[:, :3] -= self.lag * DT * X[:, 3:6]
        _, log_L = kernel_update_factors(
            np.ascontiguousarray(X), self.Z, self.u, self.axis, self.p_d_scale, ant.height, ant.tan_half, ant.r0,
            ant.n_e, np.asarray(noise_std, dtype=float), float(log_lambda_c),
        )
        return log_L


@dataclass(frozen=True)
class Young:
    """The component of s_{t-1} born at t-1: its particles at t-1 (posterior log-weights
    normalised within it), its share ``mass`` of s_{t-1} and the scans that updated it: the
    agent's own first, then the teammates' (``fusion.share: scans``)."""

    X: np.ndarray
    log_w: np.ndarray
    mass: float
    scans: tuple[Scan, ...]
    supported: np.ndarray | None = None  # per particle: L_{t-1} > 1 (kept for filter.reserve_memory)
    nu: np.ndarray | None = None  # per particle: P(visible) after the update at t-1 (filter.visibility.per_particle)


def scan_gaussians(scans: Sequence[Scan], noise_std, inflate: float = PROPOSAL_INFLATE,
                   floor: float = PROPOSAL_FLOOR) -> Gaussians | None:
    """The proposal Gaussians (:meth:`Gaussians.of_scan`) of every measurement of ``scans`` taken
    this step, in order; None when they hold none. A late scan (``lag`` > 0) saw where the target
    was, not where it is: it weighs the particles but proposes none."""
    now = [s for s in scans if s.lag == 0 and len(s.Z)]
    if not now:
        return None
    if len(now) == 1:
        return Gaussians.of_scan(now[0].Z, now[0].u, noise_std, inflate, floor)
    parts = [measurement_covariances(s.Z, s.u, noise_std, inflate, floor) for s in now]
    return Gaussians.of(np.concatenate([m for m, _ in parts]), np.concatenate([c for _, c in parts]))


@dataclass(frozen=True)
class Estimate:
    """What an agent reports: existence probability e, particle mean and covariance of s."""

    existence: float
    mean: np.ndarray  # (6,) [x, y, z, vx, vy, vz]
    cov: np.ndarray  # (6, 6)


def weighted_moments(X: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of particles ``X`` (n, d) with normalised weights ``w`` (n,)."""
    return kernel_weighted_moments(np.ascontiguousarray(X), np.ascontiguousarray(w, dtype=float))


MODE_CELL_SHARE = 0.8  # the mode's grid cell, as a share of filter.mode.radius


def mode_cluster_reference(X: np.ndarray, w: np.ndarray, radius: float, cell: float
                           ) -> tuple[np.ndarray, float, np.ndarray]:
    """Plain-numpy twin of :func:`~trackjam.estimation.kernels.kernel_mode_cluster`: the heaviest
    grid cell's weighted mean, mean-shifted MODE_SHIFTS times with a flat kernel of ``radius``;
    (centre, weight within ``radius`` of it, that mask)."""
    P = np.asarray(X, dtype=float)[:, :3]
    w = np.asarray(w, dtype=float)
    cell = max(cell, 5e-324)
    with np.errstate(over="ignore", invalid="ignore"):  # a tiny cell: inf - inf, the loop doubles it
        while True:  # counted in float64, as the kernel does: an int64 product overflows for tiny cells
            low, high = np.floor(P.min(axis=0) / cell), np.floor(P.max(axis=0) / cell)
            if (np.prod(high - low + 1.0) <= MODE_MAX_CELLS and np.abs([low, high]).max() <= MODE_MAX_INDEX) \
                    or cell == np.inf:
                break
            cell *= 2.0
    lo, dims = low.astype(np.int64), (high - low + 1.0).astype(np.int64)
    cells = np.floor(P / cell).astype(np.int64) - lo
    idx = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    best = int(np.argmax(np.bincount(idx, weights=w, minlength=int(np.prod(dims)))))
    sel = idx == best
    centre = w[sel] @ P[sel] / w[sel].sum() if w[sel].sum() > 0 else P[sel].mean(axis=0)
    for step in range(MODE_SHIFTS + 1):
        inside = np.sum((P - centre) ** 2, axis=1) < radius * radius
        mass = float(w[inside].sum())
        if step == MODE_SHIFTS or mass <= 0.0:
            break
        centre = w[inside] @ P[inside] / mass
    return centre, mass, inside


def mode_moments(X: np.ndarray, w: np.ndarray, radius: float, least: float
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """``filter.mode``: mean and covariance of the particles ``X`` within ``radius`` of the
    densest point of the weighted set (normalised weights ``w``), when they hold at least
    ``least`` of the weight; None otherwise. An empty set is refused (ValueError): the kernel
    would read past it. The filter never passes one (it holds filter.particles >= 10)."""
    X = np.ascontiguousarray(X)
    if X.shape[0] == 0:
        raise ValueError("mode_moments: no particles (the densest cluster of an empty set is undefined)")
    w = np.ascontiguousarray(w, dtype=float)
    _, mass, inside = kernel_mode_cluster(X, w, float(radius), MODE_CELL_SHARE * float(radius))
    if not mass > 0.0 or mass < least:
        return None
    return kernel_masked_moments(X, w, inside, mass)


def mixture_moments(parts: list[tuple[float, np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of a mixture given ``(weight, mean, cov)`` of each component."""
    mean = sum(a * m for a, m, _ in parts)
    second = sum(a * (C + np.outer(m, m)) for a, m, C in parts)
    cov = second - np.outer(mean, mean)
    return mean, 0.5 * (cov + cov.T)


def posterior_existence(e_pred: float, log_one_minus_q: float) -> float:
    """e_t = (1 - q_t) e_{t|t-1} / (1 - e_{t|t-1} q_t), from ``log(1 - q_t)``.

    Written as logit(e_t) = logit(e_{t|t-1}) + log(1 - q_t), which stays exact when
    1 - q_t is huge (a detection far above clutter) or tiny.
    """
    if e_pred <= 0.0 or log_one_minus_q == -np.inf:
        return 0.0
    if e_pred >= 1.0:
        return 1.0
    return float(expit(math.log(e_pred) - math.log1p(-e_pred) + log_one_minus_q))


def mix_visibility(log_L: np.ndarray, nu: float) -> np.ndarray:
    """Per-particle update factors with a hidden-target mode (ours): a visible target (P = nu)
    updates by L_i, a hidden one leaves every measurement to clutter (factor 1), so
    L'_i = nu L_i + (1 - nu)."""
    if nu >= 1.0:
        return log_L
    if nu <= 0.0:
        return np.zeros_like(log_L)
    return np.logaddexp(math.log(nu) + log_L, math.log1p(-nu))


def posterior_visibility(nu: float, log_V: float) -> float:
    """P(visible) after a scan with visible-target evidence V = sum_i w_i L_i:
    nu V / (nu V + 1 - nu)."""
    if nu <= 0.0 or nu >= 1.0:
        return float(nu)
    if log_V == -np.inf:
        return 0.0
    return float(expit(math.log(nu) - math.log1p(-nu) + log_V))


def mix_visibility_per_particle(log_w: np.ndarray, log_L: np.ndarray, nu: np.ndarray,
                                log_V_all: float | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The hidden-target mode with P(visible) carried per particle (ours,
    ``filter.visibility.per_particle``): the state is (x, visible) and the particles hold
    ``nu_i`` = P(visible | x_i). Returns the update factors ``log L'_i`` with
    ``L'_i = nu_i L_i + (1 - nu_i)``, each particle's posterior ``nu_i L_i / L'_i``, and the
    log-evidence ``log V`` with ``V = sum_i w_i nu_i L_i / nu_bar`` (``nu_bar = sum_i w_i nu_i``),
    so that ``sum_i w_i L'_i = nu_bar V + 1 - nu_bar`` as with one P(visible) for the filter.
    With every ``nu_i`` equal this is :func:`mix_visibility` and :func:`posterior_visibility`.
    Where every ``nu_i`` is 0, ``log V`` is ``log sum_i w_i L_i``, ``log_V_all`` when the caller
    has it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        log_nu = np.log(nu)
        log_vis = log_nu + log_L
        log_Lm = np.logaddexp(log_vis, np.log1p(-nu))
        nu_post = np.where(log_Lm > -np.inf, np.exp(log_vis - log_Lm), nu)
    nu_post = np.clip(np.nan_to_num(nu_post, nan=0.0), 0.0, 1.0)
    log_nu_bar = float(kernel_logsumexp(log_w + log_nu))
    if log_nu_bar == -np.inf:
        log_V = float(kernel_logsumexp(log_w + log_L)) if log_V_all is None else log_V_all
    else:
        log_V = float(kernel_logsumexp(log_w + log_vis)) - log_nu_bar
    return log_Lm, nu_post, log_V


def shift_visibility(nu: np.ndarray, w: np.ndarray, target: float) -> np.ndarray:
    """Per-particle P(visible) moved by one shift of their log-odds so that their weighted
    mean is ``target`` (fusion feedback of the team's P(visible) under
    ``filter.visibility.per_particle``); 0 and 1 give every particle that value."""
    if target <= 0.0 or target >= 1.0:
        return np.full(len(nu), float(np.clip(target, 0.0, 1.0)))
    with np.errstate(divide="ignore"):
        logit = np.log(nu) - np.log1p(-nu)
    lo, hi = -800.0, 800.0
    for _ in range(60):  # bisection on the shift: the mean is increasing in it
        c = 0.5 * (lo + hi)
        if float(w @ expit(logit + c)) < target:
            lo = c
        else:
            hi = c
    return expit(logit + 0.5 * (lo + hi))


def bernoulli_update(e_pred, X, log_w, Z, u, aim, level_w, ant: AntennaModel, noise_std, log_lambda_c):
    """The update of Section V-A on a weighted particle set (``log_w`` normalised).

    Returns ``(e_t, log_w_t, log(1 - q_t), log_L)``: the posterior existence, the posterior
    log-weights (normalised), the log of ``1 - q_t = sum_i w_i L_i`` and the per-particle
    ``log L_i``.
    """
    log_L = Scan.of(Z, u, aim, level_w, ant).log_factors(X, ant, noise_std, log_lambda_c)
    log_joint = log_w + log_L
    log_A = float(kernel_logsumexp(log_joint))
    e = posterior_existence(e_pred, log_A)
    log_post = log_w if log_A == -np.inf else log_joint - log_A
    return e, log_post, log_A, log_L


@dataclass(frozen=True)
class FilterParams:
    """What one agent's filter needs (Section V-A and ours): the model it assumes and its particles."""

    birth_prob: float  # p_b
    survival_prob: float  # p_s
    particles: int  # particles of the surviving density
    birth_particles: int  # particles of the birth density per step
    birth: str  # "uniform" | "measurement" | "mixed"
    birth_mix: float  # share of the birth that is measurement-driven under "mixed"
    measurement_birth_speed: float  # velocity spread of measurement-driven births [m/s]
    birth_speed: float  # v_b: uniform birth velocity in +-v_b per axis [m/s]
    accel_var: float  # the filter's Sigma_v scale [m^2/s^4]
    walls: str  # "reflect" | "none"
    low: np.ndarray  # (3,) area [m]
    high: np.ndarray
    noise_std: np.ndarray  # (3,) Sigma_w diagonal as standard deviations
    clutter_rate: float  # lambda_c
    visibility: tuple[float, float] | None = None  # (hide, reappear) per step; None: always visible (the paper)
    mode: tuple[float, float] | None = None  # filter.mode (radius [m], least weight); None: the mean of s_t (the paper)
    response: FailSafe | None = None  # filter.response: the fail-safe it expects of a jammed target; None: Eq. (1) always
    reserve_memory: int = 0  # filter.reserve_memory: scans before the current one whose support keeps a reserved slot
    velocity_jitter: float = 0.0  # filter.velocity_jitter [m/s]: the reserve's extra copies get N(0, this^2) per velocity axis; 0: plain copies
    visibility_per_particle: bool = False  # filter.visibility.per_particle: each particle carries its own P(visible)
    team_proposals: bool = False  # filter.team_proposals: the births' proposals and the young redraw take the teammates' scans too

    def __post_init__(self) -> None:
        # the configuration's bounds (trackjam.config); built by hand, a noise_std of one entry
        # was read past its end by the update kernel, a NaN became an existence of 0, and
        # walls="bounce" behaved as "none"
        real("birth_prob", self.birth_prob, 0.0, 1.0)
        real("survival_prob", self.survival_prob, 0.0, 1.0)
        whole("particles", self.particles, 10, 10_000_000)
        whole("birth_particles", self.birth_particles, 1, 10_000_000)
        if self.birth not in ("uniform", "measurement", "mixed"):
            raise ValueError(f"birth: expected 'uniform', 'measurement' or 'mixed', got {self.birth!r:.40}")
        real("birth_mix", self.birth_mix, 0.0, 1.0)
        real("measurement_birth_speed", self.measurement_birth_speed, 0.0)
        real("birth_speed", self.birth_speed, 0.0)
        real("accel_var", self.accel_var, 0.0)
        if self.walls not in ("reflect", "none"):
            raise ValueError(f"walls: expected 'reflect' or 'none', got {self.walls!r:.40}")
        corners(self.low, self.high)
        if np.any(vector("noise_std", self.noise_std) <= 0.0):
            raise ValueError(f"noise_std: the standard deviations must be > 0, got {np.asarray(self.noise_std).tolist()}")
        real("clutter_rate", self.clutter_rate, 0.0, 1000.0)
        if self.visibility is not None:
            if len(self.visibility) != 2:
                raise ValueError(f"visibility: expected (hide, reappear), got {self.visibility!r:.40}")
            real("visibility hide", self.visibility[0], 0.0, 1.0)
            real("visibility reappear", self.visibility[1], 0.0, 1.0)
        if self.mode is not None:
            if len(self.mode) != 2:
                raise ValueError(f"mode: expected (radius, mass), got {self.mode!r:.40}")
            real("mode radius", self.mode[0], 0.0, above=True)
            real("mode mass", self.mode[1], 0.0, 1.0, above=True)
        whole("reserve_memory", self.reserve_memory, 0, 10**6)
        real("velocity_jitter", self.velocity_jitter, 0.0)
        for name in ("visibility_per_particle", "team_proposals"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):  # "no" would have been true
                raise TypeError(f"{name}: expected True or False, got {type(getattr(self, name)).__name__} "
                                f"{getattr(self, name)!r:.40}")


class BernoulliFilter:
    """One agent's Bernoulli particle filter. Call ``predict()`` then ``update(...)`` each step."""

    def __init__(
        self,
        params: FilterParams,
        antenna: AntennaModel,
        rng: np.random.Generator,
        *,
        existence: float = 0.0,
        birth_proposal: str = "importance",
        proposal_fraction: float = 0.75,
        two_scan: bool = True,
    ):
        if birth_proposal not in ("importance", "plain"):
            raise ValueError(f"birth_proposal must be 'importance' or 'plain', got {birth_proposal!r}")
        if not 0.0 <= proposal_fraction <= 1.0:
            raise ValueError("proposal_fraction must lie in [0, 1]")
        f = params
        self.rng = rng
        self.p_b = float(f.birth_prob)
        self.p_s = float(f.survival_prob)
        self.n = int(f.particles)
        self.n_b = int(f.birth_particles)
        self.birth = f.birth
        # share of b_t that is measurement-driven: 0 for the paper's uniform birth
        self.birth_mix = {"uniform": 0.0, "measurement": 1.0, "mixed": float(f.birth_mix)}[f.birth]
        self.n_mb = int(round(self.birth_mix * self.n_b))
        self.v_m = float(f.measurement_birth_speed)
        self.accel_var = float(f.accel_var)
        self.ant = antenna
        self.noise_std = np.asarray(f.noise_std, dtype=float)
        self.lambda_c = float(f.clutter_rate)
        # lambda_c = 0 would make g / (lambda_c p_c) infinite; a tiny floor keeps logs finite
        self.log_lambda_c = math.log(max(self.lambda_c * clutter_density(self.ant.max_range), 1e-300))
        self.walls = f.walls
        self.b = UniformBirth(np.asarray(f.low, dtype=float), np.asarray(f.high, dtype=float), float(f.birth_speed))
        self.importance = birth_proposal == "importance"
        self.proposal_fraction = float(proposal_fraction)
        self.two_scan = bool(two_scan) and self.importance and self.b.v_b > 0.0 and self.n_mb < self.n_b
        # the two-scan proposal is efficient: it redraws the young component with half the
        # uniform births' count, and the survivors keep the rest of the n particles
        self.n_young = max((self.n_b - self.n_mb) // 2, 1)

        self.visibility = None if f.visibility is None else (float(f.visibility[0]), float(f.visibility[1]))
        self.mode = None if f.mode is None else (float(f.mode[0]), float(f.mode[1]))
        self.response = f.response
        self.reserve_memory = int(f.reserve_memory)
        self.velocity_jitter = float(f.velocity_jitter)
        self.watch = JamWatch()  # filter.response: the target's jammed steps in a row, and whether it is downed
        if self.mode is not None and not (self.mode[0] > 0.0 and 0.0 < self.mode[1] <= 1.0):
            raise ValueError(f"mode must be (radius > 0, least weight in (0, 1]), got {self.mode}")
        self.nu = 1.0  # P(visible | the target exists), after the last update
        self.nu_pred = 1.0  # the same predicted to the current step
        # filter.visibility.per_particle (ours): P(visible) per row of _X, after the last update,
        # and (set by predict) predicted to the current step
        self.per_particle = bool(f.visibility_per_particle) and self.visibility is not None
        self.team_proposals = bool(f.team_proposals)
        self._nu = np.ones(self.n) if self.per_particle else None
        self._nu_pred: np.ndarray | None = None
        self.log_evidence = 0.0  # log sum_i w_i L_i of the last update: its evidence were the target visible
        self.e = float(np.clip(existence, 0.0, 1.0))
        self._X = self.b.draw(self.rng, self.n)
        self._age = np.full(self.n, NEVER)  # per row of _X, kept with filter.reserve_memory: scans since one supported its line
        self._log_w = np.full(self.n, -math.log(self.n))  # normalised log-weights of s_t outside the young part
        self._young: Young | None = None
        # the two-scan proposal's Gaussians of a step's scans, kept one step: (the scans, their Gaussians)
        self._young_gaussians: tuple[tuple[Scan, ...] | None, Gaussians | None] = (None, None)
        self._e_pred: float | None = None  # set by predict(), consumed by update()
        self._w_surv = 1.0
        self._w_birth = 0.0
        self._m_birth: tuple[np.ndarray, np.ndarray] | None = None  # measurement-driven births drawn at predict
        self._prev_G: Gaussians | None = None  # the last scans' Gaussians, for measurement-driven birth
        self.weighed = 0  # particles weighed by the last update: survivors, young component and births
        mean, cov = weighted_moments(self._X, np.exp(self._log_w))
        self._last = Estimate(self.e, mean, cov)

    def draw_uniform_birth(self, Z: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``n_b`` particles of the uniform b(x) and their normalised log-weights b / proposal."""
        G = Gaussians.of_scan(Z, u, self.noise_std) if (self.importance and len(Z)) else None
        return draw_uniform_birth(self.rng, self.b, G, self.n_b, self.proposal_fraction)

    def _move(self, X: np.ndarray) -> None:
        """Eq. (1) in place, x_t = Phi x_{t-1} + Gamma nu with nu ~ N(0, accel_var I3), then the walls."""
        kernel_cv_predict(X, self.rng.standard_normal((len(X), 3)), DT, math.sqrt(self.accel_var))
        if self.walls == "reflect":
            kernel_reflect(X, self.b.low, self.b.high)

    def _chain(self, nu):
        """P(visible) predicted one step by the hidden-target mode's two-state chain."""
        hide, reappear = self.visibility
        return (1.0 - hide) * nu + reappear * (1.0 - nu)

    @property
    def _young_mass(self) -> float:
        return self._young.mass if self._young is not None else 0.0

    # -- the recursion ------------------------------------------------------------------------
    def predict(self) -> Estimate:
        """Prediction of Section V-A: e_{t|t-1} and the moments of s_{t|t-1}."""
        e_prev = self.e
        e_pred = self.p_b * (1.0 - e_prev) + self.p_s * e_prev
        if e_pred > 0.0:
            self._w_surv = self.p_s * e_prev / e_pred
            self._w_birth = self.p_b * (1.0 - e_prev) / e_pred
        else:  # no mass anywhere; keep the survivors as the (irrelevant) spatial density
            self._w_surv, self._w_birth = 1.0, 0.0
        if self.watch.downed:  # filter.response: the survivors move as the fail-safe (estimation/failsafe.py)
            move_downed(self._X, self.rng, self.response, self.accel_var, self._move, self.watch.fresh)
            self.watch = replace(self.watch, fresh=False)
        else:
            self._move(self._X)
        M = self._young_mass
        parts = [(self._w_surv * (1.0 - M), *weighted_moments(self._X, np.exp(self._log_w)))]
        if self._young is not None:
            # the young particles move in update(), where most steps draw them again; their
            # predicted moments are Eq. (1)'s linear map of their moments (walls aside)
            m_y, C_y = weighted_moments(self._young.X, np.exp(self._young.log_w))
            parts.append((self._w_surv * M, PHI @ m_y, PHI @ C_y @ PHI.T + self.accel_var * GG))
        self._e_pred = e_pred
        if self.per_particle:  # the chain per particle; a new target is born visible
            self._nu_pred = self._chain(self._nu)
            nu_s = float(np.exp(self._log_w) @ self._nu_pred)
            nu_y = float(np.exp(self._young.log_w) @ self._chain(self._young.nu)) if self._young is not None else 0.0
            self.nu_pred = self._w_surv * ((1.0 - M) * nu_s + M * nu_y) + self._w_birth * self._chain(1.0)
        elif self.visibility is not None:
            self.nu_pred = self._chain(self.nu)
        self._m_birth = None
        if self.n_mb:
            self._m_birth = draw_measurement_birth(self.rng, self.b, self._prev_G, self.n_mb, self.v_m)
            parts.append((self._w_birth * self.birth_mix, *weighted_moments(self._m_birth[0], np.exp(self._m_birth[1]))))
        if self.n_mb < self.n_b:
            parts.append((self._w_birth * (1.0 - self.birth_mix), *self.b.moments()))
        mean, cov = mixture_moments(parts)
        self._last = Estimate(e_pred, mean, cov)
        return self._last

    def _young_at_t(self, scans: tuple[Scan, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
        """The young component at t: its particles moved by predict(), or drawn again by the
        two-scan proposal when both its scans and the current ones hold measurements; with
        ``filter.reserve_memory``, also which of them their scans at t-1 supported; with
        ``filter.visibility.per_particle``, their P(visible) predicted to t (drawn again, the
        component's mean for each). ``scans``: this step's, the agent's own first."""
        young = self._young
        if self.two_scan:
            cached, G_prev = self._young_gaussians
            if cached is not young.scans:
                G_prev = scan_gaussians(young.scans, self.noise_std, YOUNG_INFLATE, YOUNG_FLOOR)
            G_next = scan_gaussians(scans, self.noise_std, YOUNG_INFLATE, YOUNG_FLOOR)
            self._young_gaussians = (scans, G_next)  # the next step's G_prev when these scans' births become young
        if self.two_scan and G_prev is not None and G_next is not None:
            log_L_prev: list[np.ndarray] = []  # L_{t-1} of the redrawn particles, as the proposal weighed them

            def weigh(X: np.ndarray) -> np.ndarray:
                # the component's density at t-1 is b times every scan's factor that weighed it
                log_L = self._log_factors(young.scans, X)
                log_L_prev.append(log_L)
                return log_L

            X0, log_w = redraw_young(self.rng, self.b, G_prev, G_next, self.n_young, self.proposal_fraction,
                                     self.accel_var, weigh)
            if np.any(np.isfinite(log_w)):
                self._move(X0)
                nu = None if young.nu is None else np.full(len(X0), self._chain(float(np.exp(young.log_w) @ young.nu)))
                return X0, log_w, log_L_prev[-1] > 0.0 if self.reserve_memory > 0 else None, nu
        X = young.X.copy()
        self._move(X)
        return X, young.log_w, young.supported, None if young.nu is None else self._chain(young.nu)

    def update(self, Z: np.ndarray, u: np.ndarray, aim: np.ndarray, level_w: float,
               others: Sequence[Scan] = ()) -> Estimate:
        """Update of Section V-A with scan ``Z`` (m, 3) taken from ``u`` with the antenna aimed at
        ``aim`` and transmitting ``level_w`` watts; then systematic resampling to ``n`` particles.
        Runs ``predict()`` first if it was not called since the last update."""
        if self._e_pred is None:
            self.predict()
        e_pred = self._e_pred
        scan = Scan.of(Z, u, aim, level_w, self.ant)
        Z, u = scan.Z, scan.u
        # filter.team_proposals: the births are proposed around every measurement of the step's
        # scans, the teammates' too (fusion.share: scans): a teammate's detection weighs them all,
        # so it must find some; else around the agent's own scan's only
        scans = (scan, *others) if self.team_proposals else (scan,)
        G_now = scan_gaussians(scans, self.noise_std) if self.importance else None
        M = self._young_mass
        young_seen = None
        nus = [self._nu_pred] if self.per_particle else None  # filter.visibility.per_particle: P(visible) per block
        with np.errstate(divide="ignore"):
            log_s, log_b = np.log(self._w_surv), np.log(self._w_birth)
            blocks = [(self._X, log_s + np.log1p(-M) + self._log_w)]
            if self._young is not None:
                XY, log_wY, young_seen, nu_Y = self._young_at_t(scans)
                blocks.append((XY, log_s + np.log(M) + log_wY))
                if nus is not None:
                    nus.append(nu_Y)
            if self.n_mb:
                blocks.append((self._m_birth[0], log_b + np.log(self.birth_mix) + self._m_birth[1]))
            n_u = self.n_b - self.n_mb
            if n_u:
                XU, log_wU = draw_uniform_birth(self.rng, self.b, G_now, n_u, self.proposal_fraction)
                blocks.append((XU, log_b + np.log1p(-self.birth_mix) + log_wU))
        X = np.vstack([x for x, _ in blocks])
        log_w = np.concatenate([lw for _, lw in blocks])
        self.weighed = len(X)
        log_L = self._log_factors((scan, *others), X)  # teammates' scans: independent of this one given the target
        log_wL = log_w + log_L
        log_V = float(kernel_logsumexp(log_wL))
        self.log_evidence = log_V
        log_Lm = log_L
        nu_post = None
        if self.per_particle:
            nu_all = np.concatenate(nus + [np.full(len(X) - sum(len(v) for v in nus), self._chain(1.0))])
            log_Lm, nu_post, self.log_evidence = mix_visibility_per_particle(log_w, log_L, nu_all, log_V)
        elif self.visibility is not None:
            log_Lm = mix_visibility(log_L, self.nu_pred)
            self.nu = posterior_visibility(self.nu_pred, log_V)
        if log_Lm is log_L:  # no hidden-target mode: the joint and its sum are the evidence's
            log_joint, log_A = log_wL, log_V
        else:
            log_joint = log_w + log_Lm
            log_A = float(kernel_logsumexp(log_joint))
        e = posterior_existence(e_pred, log_A)
        log_post = log_w if log_A == -np.inf else log_joint - log_A
        w = np.exp(log_post)
        w /= w.sum()
        if nu_post is not None:
            self.nu = float(np.clip(w @ nu_post, 0.0, 1.0))
        at_mode = None if self.mode is None else mode_moments(X, w, *self.mode)
        mean, cov = at_mode or weighted_moments(X, w)
        # the uniform-born part becomes the young component, the rest is resampled to the
        # particles left of n: the step keeps n + n_b particles in all
        k = len(X) - n_u if self.two_scan else len(X)
        W_pool = float(w[:k].sum())
        if W_pool > 0.0:
            n_pool = max(self.n - self.n_young, self.n // 2) if k < len(X) else self.n
            supported = log_L[:k] > 0.0
            if self.reserve_memory > 0:  # scans since a scan supported each row's line
                age = np.full(k, NEVER)  # the pool: the survivors' rows first, then the young component's
                n_s = len(self._X)
                age[:n_s] = np.minimum(self._age, NEVER - 1) + 1
                if young_seen is not None:  # the young component: supported by its scan at t-1
                    age[n_s:n_s + len(young_seen)][young_seen] = 1
                age[supported] = 0
                supported = age <= self.reserve_memory
            self._X, self._log_w, parents = self._resample(X[:k], w[:k] / W_pool, supported, n_pool)
            if self.reserve_memory > 0:
                self._age = age[parents]
            if nu_post is not None:
                self._nu = nu_post[:k][parents]
        self._young = None
        if k < len(X):
            log_mass = float(kernel_logsumexp(log_post[k:]))
            if log_mass > -np.inf:
                self._young = Young(X[k:], log_post[k:] - log_mass, min(math.exp(log_mass), 1.0), scans,
                                    log_L[k:] > 0.0 if self.reserve_memory > 0 else None,
                                    None if nu_post is None else nu_post[k:].copy())
        self.e = e
        self._e_pred = None
        self._m_birth = None
        if self.n_mb:
            self._prev_G = scan_gaussians(scans, self.noise_std, inflate=1.0)
        self._last = Estimate(e, mean, cov)
        return self._last

    def _resample(self, X: np.ndarray, w: np.ndarray, supported: np.ndarray,
                  n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Systematic resampling of the weighted particles to ``n``: the particles, their
        log-weights and the index of each one's parent.

        ``supported`` marks the particles the scan made more likely (L_i > 1: near a
        measurement), and with ``filter.reserve_memory`` = m (ours) those whose line one of the
        m scans before it did, so that a track seen once and missed at the next scan keeps its
        slots. While a target is new, they carry well under 1% of the mass next to the diffuse
        "somewhere else in the area" part, so plain resampling keeps a few dozen of them, too
        few to find the velocity, unobserved at a first detection. When their share
        would give them fewer than ``min(RESERVE_CAP n_b, RESERVE_SHARE n)`` = ``min(3 n_b, 0.4 n)`` slots, the two parts are resampled
        separately (ours): the supported part gets that many slots, the rest the others, each
        slot weighted by its part's mass over its slot count. The weighted set represents the
        same density; once the target is tracked the supported part dominates and this is
        plain systematic resampling.

        With ``filter.velocity_jitter`` = sigma > 0 (ours), the reserved slots are regularised:
        every copy of a supported particle after its first gets N(0, sigma^2) added to each
        velocity component (the kernel step of a regularised particle filter, Musso, Oudjane
        and Le Gland 2001). A new track's supported particles descend from a few parents whose
        velocities the scans have not pinned down yet; without the kernel their copies share a
        velocity and only Eq. (1)'s noise spreads them again.
        """
        reserve = min(RESERVE_CAP * self.n_b, int(RESERVE_SHARE * n))
        # the masses' in-order sums decide the plain case when they lie far from its thresholds
        # (the weights are >= 0: an in-order sum is 0 exactly when numpy's is, and the two differ
        # by far less than the 1e-6 margin); else numpy's sums decide, and weigh the split
        s_a, s_r = kernel_split_sums(w, supported) if reserve else (1.0, 1.0)
        plain = reserve == 0 or s_a == 0.0 or s_r == 0.0 or s_a * n >= reserve * (1.0 + 1e-6)
        if not plain:
            W_a = float(w[supported].sum())
            W_r = float(w[~supported].sum())
            plain = W_a <= 0.0 or W_r <= 0.0 or W_a * n >= reserve
        if plain:
            idx = kernel_systematic_indices(w, n, self.rng.uniform())
            return kernel_take_rows(X, idx), np.full(n, -math.log(n)), idx
        ia = np.flatnonzero(supported)
        ir = np.flatnonzero(~supported)
        n_r = n - reserve
        idx_a = ia[kernel_systematic_indices(w[ia] / W_a, reserve, self.rng.uniform())]
        idx_r = ir[kernel_systematic_indices(w[ir] / W_r, n_r, self.rng.uniform())]
        log_w = np.concatenate([np.full(reserve, math.log(W_a / reserve)), np.full(n_r, math.log(W_r / n_r))])
        idx = np.concatenate([idx_a, idx_r])
        X_new = kernel_take_rows(X, idx)
        if self.velocity_jitter > 0.0:
            copies = np.flatnonzero(idx_a[1:] == idx_a[:-1]) + 1  # systematic indices are sorted: copies are adjacent
            X_new[copies, 3:] += self.velocity_jitter * self.rng.standard_normal((len(copies), 3))
        return X_new, log_w, idx

    def estimate(self) -> Estimate:
        """The latest estimate: predicted after ``predict()``, posterior after ``update()``."""
        return self._last

    def reset_to(self, existence: float, mean: np.ndarray | None = None, cov: np.ndarray | None = None,
                 visible: float | None = None) -> None:
        """Fusion feedback (end of Section V-A), called after ``update()``: set the existence
        (and, with a hidden-target mode, P(visible)); when a fused Gaussian is given, redraw the
        particles from N(mean, cov) (equal weights; a singular covariance is allowed)."""
        self.e = float(np.clip(existence, 0.0, 1.0))
        if visible is not None and self.visibility is not None:
            self.nu = float(np.clip(visible, 0.0, 1.0))
            if self.per_particle and mean is None:  # keep the particles' differences, at the team's mean
                self._nu = shift_visibility(self._nu, np.exp(self._log_w), self.nu)
        if mean is not None and cov is not None:
            mean = np.asarray(mean, dtype=float)
            cov = np.asarray(cov, dtype=float)
            lam, V = np.linalg.eigh(0.5 * (cov + cov.T))
            root = V * np.sqrt(np.clip(lam, 0.0, None))
            self._X = mean + self.rng.standard_normal((self.n, 6)) @ root.T
            self._age = np.full(self.n, NEVER)
            self._log_w = np.full(self.n, -math.log(self.n))
            if self.per_particle:
                self._nu = np.full(self.n, self.nu)
            self._young = None
            self._last = Estimate(self.e, mean.copy(), cov.copy())
            if self.watch.downed:  # the redrawn particles take the hedge's branches again
                self.watch = replace(self.watch, fresh=True)
        else:
            self._last = Estimate(self.e, self._last.mean, self._last.cov)

    def shift_to(self, mean: np.ndarray) -> None:
        """Move every particle of the surviving density (:attr:`particles`, the young component's
        included) by one offset, so that their weighted mean is ``mean``: the belief keeps its
        spread and shape and is centred elsewhere (``oracle.mean_before_hiding``, a diagnostic).
        Called after ``update()``."""
        X, log_w = self._survivors()
        w = np.exp(log_w - log_w.max())
        offset = np.asarray(mean, dtype=float) - (w / w.sum()) @ X
        self._X = self._X + offset
        if self._young is not None:
            self._young = replace(self._young, X=self._young.X + offset)
        self._last = Estimate(self._last.existence, self._last.mean + offset, self._last.cov)

    def note_jamming(self, positions: np.ndarray, points: np.ndarray, levels_w: np.ndarray) -> None:
        """``filter.response``, after the step's update (and fusion): count the step as jammed
        when the team's cones (senders at ``positions`` aimed at ``points`` with ``levels_w``)
        deliver the threshold to at least half of the posterior weight; the target is downed
        after the response's steps in a row (:mod:`trackjam.estimation.failsafe`). Nothing
        without a response."""
        if self.response is None:
            return
        self.watch = watched(self.watch, self.e > 0.5, self._survivors, positions, points, levels_w, self.ant,
                             self.response)

    def _survivors(self) -> tuple[np.ndarray, np.ndarray]:
        """The surviving density's particles and normalised log-weights: the resampled part and,
        while one is kept, the young component by its mass (after ``predict()`` the young
        particles, which move in ``update()``, are shown moved by Eq. (1)'s mean and the walls)."""
        if self._young is None:
            return self._X, self._log_w
        Y = self._young.X
        if self._e_pred is not None:
            Y = np.ascontiguousarray(Y @ PHI.T)
            if self.walls == "reflect":
                kernel_reflect(Y, self.b.low, self.b.high)
        M = self._young.mass
        with np.errstate(divide="ignore"):
            log_w = np.concatenate([np.log1p(-M) + self._log_w, np.log(M) + self._young.log_w])
        return np.vstack([self._X, Y]), log_w

    @property
    def visible(self) -> np.ndarray | None:
        """With ``filter.visibility.per_particle``, each of :attr:`particles`' P(visible): after
        ``predict()`` predicted to the current step, after ``update()`` the posterior; else None."""
        if not self.per_particle:
            return None
        predicted = self._e_pred is not None and self._nu_pred is not None
        nu = self._nu_pred if predicted else self._nu
        if self._young is None:
            return nu
        nu_y = self._chain(self._young.nu) if predicted else self._young.nu
        return np.concatenate([nu, nu_y])

    def _log_factors(self, scans: Sequence[Scan], X: np.ndarray) -> np.ndarray:
        """log of the product of ``scans``' factors L at the particles ``X`` (scans independent
        given the target), summed in their order, the first's first."""
        log_L = scans[0].log_factors(X, self.ant, self.noise_std, self.log_lambda_c)
        for other in scans[1:]:
            log_L = log_L + other.log_factors(X, self.ant, self.noise_std, self.log_lambda_c)
        return log_L

    def survivors(self) -> tuple[np.ndarray, np.ndarray]:
        """:attr:`particles` and :attr:`log_w` together, built once (each property builds both)."""
        return self._survivors()

    @property
    def particles(self) -> np.ndarray:
        """The particles of the surviving density s: s_t after ``update()``, the survivors moved
        to t after ``predict()`` (births not included); weights ``exp(log_w)``."""
        return self._survivors()[0]

    @property
    def log_w(self) -> np.ndarray:
        """Normalised log-weights of :attr:`particles`."""
        return self._survivors()[1]
