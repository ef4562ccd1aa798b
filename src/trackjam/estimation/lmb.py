"""One agent's labelled multi-Bernoulli (LMB) particle filter (Reuter, Vo, Vo & Dietmayer, IEEE
TSP 2014) whose tracks are the Bernoulli components of Section V-A (ours: several targets).

A track is a label (the step it entered the filter, the index in the previous step's scan of
the measurement that started it; (0, k): the cue's track of target k), an existence r
and a weighted particle set of the 6-D state. Prediction: r <- p_s r, each particle moved by
Eq. (1) (and the walls, as in the Bernoulli filter). Update with one scan: the weights eta of
:mod:`trackjam.estimation.lmb_association` from the per-particle p_D (Eq. 9) and
g(y | x) / (lambda_c p_c(y)), the marginals beta of the joint association hypotheses (Gibbs
sampling or a ranked assignment), then the LMB approximation per track:

    r_i' = sum_{j} beta[i, 1 + j] + beta[i, 0] r_i <1 - p_D>_i / eta[i, 0],
    s_i'(x) ∝ [beta[i, 0] r_i (1 - p_D(x)) / eta[i, 0]
               + sum_j beta[i, 1 + j] p_D(x) g(y_j | x) / (lambda_c p_c) / <p_D g_j / (lambda_c p_c)>_i] s_i(x)

(<f>_i = ∫ f s_i). With one track this is the Bernoulli update of Section V-A exactly.

Hidden-target mode (ours, ``visibility``): each track also carries nu = P(visible | it exists),
predicted by the two-state chain nu <- (1 - hide) nu + reappear (1 - nu); the update uses
nu p_D(x) for p_D(x) and leaves nu' = [sum_j beta[i, 1 + j] + m_i nu <1 - p_D>_i /
<1 - nu p_D>_i] / r_i', m_i the exists-and-missed share of r_i' (:func:`posterior_visible`).

Adaptive birth (Reuter et al., Sec. IV-A): measurement y_j of the scan at t starts a track that
enters at t + 1 with existence min(r_B^max, lambda_B (1 - r_U(y_j)) / sum_y (1 - r_U(y))),
r_U(y_j) = sum_i beta[i, 1 + j] the probability that y_j was some track's. Its density is that
of a target seen once by this scan (ours: the single-measurement posterior
∝ p_D(x) g(y_j | x) over the area, velocity uniform in ±v): particles from the measurement's
Cartesian Gaussian weighted by p_D g / Gaussian, so a measurement from where the cone cannot
detect starts no track.

Tracks below the pruning threshold are dropped, the most likely ``max_tracks`` kept, and each
track is resampled (systematic) to its particle count: ``particles`` once it has been confirmed
(r > 0.5), a birth's count before (ours). Most tracks are never confirmed: clutter starts them,
and where p_D is small (far along the cone) misses barely lower their r, so they linger; the
density of a track that once held a target, hidden or lost since, keeps a target's particles
(giving every track particles in proportion to r halved the step time but re-found a target
after a hidden spell less often than the Bernoulli filter).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from trackjam.arguments import corners, numeric, real, vector, whole
from trackjam.estimation.bernoulli import DT, Scan, weighted_moments
from trackjam.estimation.birth import Gaussians, UniformBirth
from trackjam.estimation.failsafe import FailSafe, JamWatch, move_downed, watched
from trackjam.estimation.kernels import (
    GATE,
    kernel_cv_predict,
    kernel_logsumexp,
    kernel_reflect,
    kernel_systematic_indices,
)
from trackjam.estimation.lmb_association import association_marginals
from trackjam.estimation.lmb_kernels import (
    kernel_association_factors,
    kernel_ball,
    kernel_beyond_cone,
    kernel_log_means,
    kernel_mixture_log_weights,
    kernel_seen_factors,
)
from trackjam.radio.antenna import AntennaModel
from trackjam.radio.measurement import CLUTTER_RATE_MAX, clutter_density

DT = 1.0  # dT [s]
CONFIRM = 0.5  # a track is confirmed once r > 0.5 (Section V-A's e > 0.5)
BIRTH_FLOOR = 0.1  # smallest standard deviation per axis of a birth's position Gaussian [m] (ours)
CONE_MARGIN = 1e-6  # [m] a track's particles this far outside a scan's cone skip its kernel (10^3 x its tolerance)
# LMBParams' budgets where the configuration sets no bound (it fixes these fields): lambda_B up to
# the clutter's bound (births come one per measurement), at most 1000 tracks (the ranked
# assignment is cubic in them), 10^6 Gibbs sweeps (the sampler draws sweeps x tracks uniforms at
# once: 160 MB at 20 tracks) and 10^4 ranked hypotheses (one assignment solved per hypothesis)
BIRTH_RATE_MAX = CLUTTER_RATE_MAX
# the configuration's bounds (config/limits.py), mirrored since the engine's packages do not
# import the configuration (tests/test_layout.py); tests/test_config_hostile.py holds them equal
MAX_SPEED = 1e3  # m/s
MAX_ACCEL_VAR = 1e4  # m^2/s^4
MAX_TRACKS_LIMIT = 1000
GIBBS_SAMPLES_MAX = 1_000_000
RANKED_K_MAX = 10_000


@dataclass(frozen=True)
class LMBParams:
    """What one agent's LMB filter needs: the model it assumes, its births and its budgets."""

    survival_prob: float  # p_s
    particles: int  # particles of a confirmed track after an update
    birth_particles: int  # particles of a track born around one measurement, and of a track never confirmed
    birth_rate: float  # lambda_B: expected number of births per step (adaptive birth)
    birth_existence_max: float  # r_B^max: cap on a birth's existence
    birth_speed: float  # a birth's velocity, uniform in ±v per axis [m/s]
    accel_var: float  # the filter's Sigma_v scale [m^2/s^4]
    walls: str  # "reflect" | "none"
    low: np.ndarray  # (3,) area [m]
    high: np.ndarray
    noise_std: np.ndarray  # (3,) Sigma_w diagonal as standard deviations
    clutter_rate: float  # lambda_c
    prune: float = 1e-3  # tracks with r below this are dropped
    max_tracks: int = 20  # at most this many tracks, the most likely (clutter-born ones fill it)
    association: str = "gibbs"  # "gibbs" | "ranked"
    gibbs_samples: int = 1000  # Gibbs sweeps per update
    ranked_k: int = 200  # hypotheses of the ranked assignment
    association_misses: bool = False  # filter.association_misses: Gibbs also weighs each track's miss of the best hypothesis
    visibility: tuple[float, float] | None = None  # (hide, reappear) per step: the hidden-target mode; None: always visible
    response: FailSafe | None = None  # filter.response: the fail-safe it expects of a jammed target; None: Eq. (1) always

    def __post_init__(self):
        # every field, with the configuration's bounds where it has them (trackjam.config:
        # filter.*, sensor.*, area.*) and budgets where it does not: built by hand, accel_var=-1
        # was a "math domain error", noise_std 0 a ZeroDivisionError, a negative clutter_rate an
        # existence of 1, a NaN made every track vanish, gibbs_samples=10**12 a MemoryError
        real("survival_prob", self.survival_prob, 0.0, 1.0)
        whole("particles", self.particles, 1, 10_000_000)  # a track's particles: a hand-made set may hold a few
        whole("birth_particles", self.birth_particles, 1, 10_000_000)
        real("birth_rate", self.birth_rate, 0.0, BIRTH_RATE_MAX)
        if not 0.0 < real("birth_existence_max", self.birth_existence_max) < 1.0:
            raise ValueError(f"birth_existence_max: must lie in (0, 1), got {float(self.birth_existence_max)!r}")
        real("birth_speed", self.birth_speed, 0.0, MAX_SPEED)
        real("accel_var", self.accel_var, 0.0, MAX_ACCEL_VAR)
        if self.walls not in ("reflect", "none"):
            raise ValueError(f"walls: expected 'reflect' or 'none', got {self.walls!r:.40}")
        corners(self.low, self.high)
        if np.any(vector("noise_std", self.noise_std) <= 0.0):
            raise ValueError(f"noise_std: the standard deviations must be > 0, got {np.asarray(self.noise_std).tolist()}")
        real("clutter_rate", self.clutter_rate, 0.0, CLUTTER_RATE_MAX)
        real("prune", self.prune, 0.0, 1.0)
        whole("max_tracks", self.max_tracks, 1, MAX_TRACKS_LIMIT)
        if self.association not in ("gibbs", "ranked"):
            raise ValueError(f"association: expected 'gibbs' or 'ranked', got {self.association!r:.40}")
        whole("gibbs_samples", self.gibbs_samples, 1, GIBBS_SAMPLES_MAX)
        whole("ranked_k", self.ranked_k, 1, RANKED_K_MAX)
        if not isinstance(self.association_misses, (bool, np.bool_)):
            raise TypeError(f"association_misses: expected True or False, got {type(self.association_misses).__name__}")
        if self.visibility is not None:
            if isinstance(self.visibility, (str, bytes)) or len(self.visibility) != 2:
                raise ValueError(f"visibility: expected (hide, reappear), got {self.visibility!r:.40}")
            real("visibility hide", self.visibility[0], 0.0, 1.0)
            real("visibility reappear", self.visibility[1], 0.0, 1.0)
        if self.response is not None and not isinstance(self.response, FailSafe):
            raise TypeError(f"response: expected a FailSafe or None, got {type(self.response).__name__}")


@dataclass(frozen=True)
class Track:
    """One Bernoulli component: label (birth step, index), existence r, particles ``X`` (n, 6)
    and their normalised log-weights; ``confirmed`` once r has exceeded 0.5 after an update;
    ``nu`` P(visible | it exists) under the hidden-target mode (1 without it)."""

    label: tuple[int, int]
    r: float
    X: np.ndarray
    log_w: np.ndarray
    confirmed: bool = False
    nu: float = 1.0
    watch: JamWatch = JamWatch()  # filter.response: its jammed steps in a row, and whether it is downed


@dataclass(frozen=True)
class TrackEstimate:
    """What an agent reports of one track: its label, existence, particle mean and covariance."""

    label: tuple[int, int]
    existence: float
    mean: np.ndarray  # (6,)
    cov: np.ndarray  # (6, 6)
    visible: float = 1.0  # P(visible | it exists) under the hidden-target mode; 1 without it


@dataclass(frozen=True)
class Factors:
    """Per track of one scan: ``seen`` (k,) the particles with p_D > 0 (ascending), and at them
    ``log_miss`` (k,) log(1 - p_D), ``log_p_d`` (k,) log p_D and ``log_g`` (k, m) log g(y_j |
    x) / kappa (the factor of column 1 + j is log_p_d + log_g[:, j]); every other particle has
    the factor 1 in column 0 and 0 in the others. ``log_mean`` (m + 1,) the factors' means <f_c>
    over the track's density; ``log_eta`` (m + 1,) the track's row of eta."""

    seen: np.ndarray
    log_miss: np.ndarray
    log_p_d: np.ndarray
    log_g: np.ndarray
    log_mean: np.ndarray
    log_eta: np.ndarray


def track_factors(track: Track, scan: Scan, ant: AntennaModel, noise_std, log_kappa: float,
                  ball: tuple[np.ndarray, float] | None = None) -> Factors:
    """The association weights of one track for one scan (the module docstring of
    :mod:`trackjam.estimation.lmb_association`); ``ball`` (centre, radius) holds the track's
    particles (:func:`kernel_ball`, computed here when not given): a track whose ball lies
    outside the scan's cone has p_D = 0 at every particle, known without visiting them."""
    X = np.ascontiguousarray(track.X)
    centre, radius = kernel_ball(X) if ball is None else ball
    if scan.p_d_scale <= 0.0 or kernel_beyond_cone(centre, radius, scan.u, scan.axis, ant.height, ant.tan_half,
                                                   CONE_MARGIN):
        seen, p_d, log_g = np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, len(scan.Z)))
    else:
        seen, p_d, log_g = kernel_seen_factors(
            X, scan.Z, scan.u, scan.axis, scan.p_d_scale, ant.height, ant.tan_half, ant.r0, ant.n_e,
            np.asarray(noise_std, dtype=float), float(log_kappa),
        )
    if track.nu < 1.0:  # hidden-target mode: a particle is seen with probability nu p_D
        p_d = track.nu * p_d
    with np.errstate(divide="ignore"):  # p_D = 1 leaves no miss; nu = 0 no detection
        log_miss = np.log1p(-np.minimum(p_d, 1.0))
        log_p_d = np.log(p_d)
    log_mean = kernel_log_means(track.log_w, seen, log_miss, log_p_d, log_g)
    log_r = math.log(track.r) if track.r > 0.0 else -np.inf
    log_not = math.log1p(-track.r) if track.r < 1.0 else -np.inf
    log_eta = log_r + log_mean
    log_eta[0] = np.logaddexp(log_not, log_r + log_mean[0])
    return Factors(seen, log_miss, log_p_d, log_g, log_mean, log_eta)


def posterior_track(track: Track, f: Factors, beta_row: np.ndarray) -> Track:
    """The LMB approximation of one track after the association (the module docstring)."""
    if track.r <= 0.0:
        return replace(track, r=0.0)
    log_mean = f.log_mean
    with np.errstate(divide="ignore"):
        log_r = math.log(track.r)
        log_beta = np.log(beta_row)
        # the share of "undetected" in which the track exists and was missed: none when a track
        # that exists is never missed (p_D = 1 at every particle: antenna.p_d_max 1 within R_0),
        # where r = 1 also made eta's 0 - inf - (-inf) a NaN existence
        log_coef = log_beta.copy()
        if log_r + log_mean[0] == -np.inf:
            log_coef[0] = -np.inf
        else:
            log_coef[0] = log_beta[0] + log_r + log_mean[0] - f.log_eta[0]
    r_new = float(np.exp(kernel_logsumexp(log_coef)))
    if r_new <= 0.0:
        return replace(track, r=0.0)
    usable = np.isfinite(log_coef) & np.isfinite(log_mean)
    coef = np.where(usable, log_coef - np.where(usable, log_mean, 0.0), -np.inf)
    log_post = kernel_mixture_log_weights(track.log_w, f.seen, f.log_miss, f.log_p_d, f.log_g, coef)
    return replace(track, r=min(r_new, 1.0), log_w=log_post, nu=posterior_visible(track.nu, log_coef, log_mean[0]))


def posterior_visible(nu: float, log_coef: np.ndarray, log_miss_mean: float) -> float:
    """P(visible | exists) after the update (hidden-target mode, ours): a detected track is
    visible; one that exists and was missed is visible with nu <1 - p_D> / <1 - nu p_D>, and
    <1 - nu p_D> = exp(``log_miss_mean``) gives nu <1 - p_D> = <1 - nu p_D> - (1 - nu). With one
    track and one scan this is the Bernoulli filter's nu V / (nu V + 1 - nu)."""
    if nu >= 1.0:
        return 1.0
    detected = float(np.exp(kernel_logsumexp(log_coef[1:]))) if len(log_coef) > 1 else 0.0
    missed = float(np.exp(log_coef[0]))
    m0 = math.exp(log_miss_mean)
    nu_missed = max(m0 - (1.0 - nu), 0.0) / m0 if m0 > 0.0 else 0.0
    total = detected + missed
    return float(min((detected + missed * nu_missed) / total, 1.0)) if total > 0.0 else nu


def retrodicted(track: Track, lag: int) -> Track:
    """The track with each particle moved back ``lag`` steps by Eq. (1) without its noise, x -
    lag dT v (ours, as :meth:`Scan.log_factors` for the Bernoulli filter; walls are ignored): a
    teammate's scan that arrived ``lag`` steps late is weighed there. The particles' indices,
    and so the weights the update gives them, are the track's own."""
    X = np.array(track.X, dtype=float)
    X[:, :3] -= lag * DT * X[:, 3:6]
    return replace(track, X=X)


def lmb_update(tracks: list[Track], scan: Scan, ant: AntennaModel, noise_std, log_kappa: float,
               rng: np.random.Generator, method: str = "gibbs", samples: int = 1000, k: int = 200,
               balls: Sequence[tuple[np.ndarray, float]] | None = None, misses: bool = False):
    """The update of all tracks by one scan. Returns ``(tracks, beta, r_U)``: the posterior
    tracks (not resampled, not pruned), the association marginals (T, m + 1) and r_U (m,), the
    probability that each measurement was some track's. ``balls[i]`` holds track i's particles
    (:func:`track_factors`; the particles do not move within an update, so one ball serves every
    scan of it)."""
    m = len(scan.Z)
    if scan.lag:  # a teammate's late scan (comms.stale: coast) is weighed where each particle was then
        factors = [track_factors(retrodicted(t, scan.lag), scan, ant, noise_std, log_kappa) for t in tracks]
    else:
        factors = [track_factors(t, scan, ant, noise_std, log_kappa, None if balls is None else balls[i])
                   for i, t in enumerate(tracks)]
    log_eta = np.array([f.log_eta for f in factors]).reshape(len(tracks), m + 1)
    beta = association_marginals(log_eta, method, rng, samples, k, misses)
    posterior = [posterior_track(t, f, b) for t, f, b in zip(tracks, factors, beta)]
    return posterior, beta, beta[:, 1:].sum(axis=0)


def birth_existences(r_U: np.ndarray, rate: float, r_max: float) -> np.ndarray:
    """Adaptive birth's r_B(y_j) = min(r_B^max, lambda_B (1 - r_U(y_j)) / sum_y (1 - r_U(y)))."""
    free = np.clip(1.0 - np.asarray(r_U, dtype=float), 0.0, 1.0)
    total = free.sum()
    if total <= 0.0:
        return np.zeros_like(free)
    return np.minimum(r_max, rate * free / total)


def draw_birth(rng: np.random.Generator, scan: Scan, j: int, n: int, b: UniformBirth, ant: AntennaModel,
               noise_std, log_kappa: float) -> tuple[np.ndarray, np.ndarray] | None:
    """``n`` particles of the density of a target seen once as measurement j of ``scan``,
    ∝ p_D(x) g(y_j | x) in the area, velocity from ``b`` (uniform in ±v_b); their normalised
    log-weights, or None when no particle could have made the measurement."""
    G = Gaussians.of_scan(scan.Z[j:j + 1], scan.u, noise_std, 1.0, BIRTH_FLOOR)
    X = b.draw(rng, n)
    X[:, :3] = G.sample(rng, n)
    p_d, log_g = kernel_association_factors(
        X, scan.Z[j:j + 1], scan.u, scan.axis, scan.p_d_scale, ant.height, ant.tan_half, ant.r0, ant.n_e,
        np.asarray(noise_std, dtype=float), float(log_kappa),
    )
    with np.errstate(divide="ignore"):
        log_w = np.log(p_d) + log_g[:, 0] - G.log_pdf(X[:, :3])
    log_w[~b.in_area(X[:, :3])] = -np.inf
    if not np.any(np.isfinite(log_w)):
        return None
    return X, log_w - kernel_logsumexp(log_w)


def _point(name: str, value) -> np.ndarray:
    """A finite 3-vector; the engine's float arrays take the short way (about 1 us)."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (3,):
        if np.isfinite(value).all():
            return value
    return vector(name, value)


def _update_arguments(Z, u, aim, level_w, others, ant: AntennaModel, noise_std: np.ndarray) -> Sequence[Scan]:
    """LMBFilter.update's checks (about 7 us on the engine's arrays): ``Z`` finite rows of 3
    (an empty list: no measurement) whose range is above -GATE range deviations (no target or
    clutter makes one below: the kernels' gate drops it), ``u`` and ``aim`` finite 3-vectors,
    ``level_w`` in [0, l_max], ``others`` Scans (any iterable, returned as a list or tuple)."""
    a = Z if type(Z) is np.ndarray and Z.dtype == np.float64 else numeric("Z", Z)
    if a.ndim != 2 or a.shape[1] != 3:
        if not (a.ndim == 1 and a.size == 0):
            raise ValueError(f"Z: expected rows of 3 entries (m, 3) [rho, azimuth, inclination], got shape {a.shape}")
    elif len(a):
        if not np.isfinite(a).all():
            raise ValueError(f"Z: must be finite, got {'NaN' if np.isnan(a).any() else 'an infinite value'}")
        low = -GATE * float(noise_std[0])
        if a[:, 0].min() < low:
            raise ValueError(f"Z: a range (first entry) below -{GATE:g} range deviations ({low:g} m) is no "
                             f"measurement, got {float(a[:, 0].min())!r}")
    _point("u", u)
    _point("aim", aim)
    real("level_w", level_w, 0.0, ant.l_max)
    if not isinstance(others, (list, tuple)):
        if not isinstance(others, Iterable) or isinstance(others, (str, bytes, Scan)):
            raise TypeError(f"others: expected a list of the teammates' Scans, got {type(others).__name__}")
        others = list(others)
    for i, other in enumerate(others):
        if not isinstance(other, Scan):
            raise TypeError(f"others[{i}]: expected a Scan (Scan.of(Z, u, aim, level_w, ant)), got {type(other).__name__}")
    return others


class LMBFilter:
    """One agent's LMB filter. Call ``predict()`` then ``update(...)`` each step; ``tracks``
    holds the current Bernoulli components."""

    def __init__(self, params: LMBParams, antenna: AntennaModel, rng: np.random.Generator):
        self.p = params
        self.ant = antenna
        self.rng = rng
        self.noise_std = np.asarray(params.noise_std, dtype=float)
        self.b = UniformBirth(np.asarray(params.low, dtype=float), np.asarray(params.high, dtype=float),
                              float(params.birth_speed))
        # lambda_c = 0 would make g / (lambda_c p_c) infinite; a tiny floor keeps logs finite
        self.log_kappa = math.log(max(params.clutter_rate * clutter_density(antenna.max_range), 1e-300))
        self.step = 0  # steps predicted so far; a track born by scan t is labelled (t + 1, j)
        self.tracks: list[Track] = []
        self._births: list[Track] = []  # born by the last scan, entering at the next prediction
        self._predicted = False

    def _move(self, X: np.ndarray) -> None:
        kernel_cv_predict(X, self.rng.standard_normal((len(X), 3)), DT, math.sqrt(self.p.accel_var))
        if self.p.walls == "reflect":
            kernel_reflect(X, self.b.low, self.b.high)

    def predict(self) -> list[TrackEstimate]:
        """r <- p_s r and Eq. (1) for every track; the last scan's births join with r_B."""
        self.step += 1
        moved = []
        vis = self.p.visibility
        for t in self.tracks:
            X = t.X.copy()
            watch = t.watch
            if watch.downed:  # filter.response: a downed track moves as the fail-safe
                move_downed(X, self.rng, self.p.response, self.p.accel_var, self._move, watch.fresh)
                watch = replace(watch, fresh=False)
            else:
                self._move(X)
            nu = t.nu if vis is None else (1.0 - vis[0]) * t.nu + vis[1] * (1.0 - t.nu)
            moved.append(replace(t, r=self.p.survival_prob * t.r, X=X, nu=nu, watch=watch))
        for t in self._births:
            X = t.X.copy()
            self._move(X)
            moved.append(replace(t, X=X))
        self.tracks, self._births = moved, []
        self._predicted = True
        return self.estimates()

    def update(self, Z: np.ndarray, u: np.ndarray, aim: np.ndarray, level_w: float,
               others: Sequence[Scan] = ()) -> list[TrackEstimate]:
        """Update by scan ``Z`` (m, 3) taken from ``u`` with the antenna aimed at ``aim`` and
        transmitting ``level_w`` watts, then by each of the teammates' scans ``others`` in turn
        (the iterated corrector: the scans are independent given the targets, and with one track
        this is the Bernoulli update by the product of their factors, up to rounding: r is a
        probability, so odds beyond 1e16 after one scan round it to 1, which no later scan
        lowers); a teammate's late scan (``Scan.late``, ``comms.stale: coast``) is weighed at
        the particles retrodicted to its step (:func:`retrodicted`); then the births of the own
        scan, pruning, the cap and resampling. Runs
        ``predict()`` first if it was not called since the last update.

        Checked first (about 7 us): ``Z`` finite (m, 3) rows (an empty list: no
        measurement) with ranges above -11 range deviations, ``u`` and ``aim`` finite 3-vectors,
        ``level_w`` in [0, l_max], ``others`` Scans; before, a NaN position or level removed every
        track and a (3, 2) or (6,) ``Z`` was silently read as rows of 3."""
        others = _update_arguments(Z, u, aim, level_w, others, self.ant, self.noise_std)
        if not self._predicted:
            self.predict()
        scan = Scan.of(Z, u, aim, level_w, self.ant)
        p = self.p
        ball = {t.label: kernel_ball(np.ascontiguousarray(t.X)) for t in self.tracks}
        posterior, _, r_U = lmb_update(self.tracks, scan, self.ant, self.noise_std, self.log_kappa, self.rng,
                                       p.association, p.gibbs_samples, p.ranked_k, [ball[t.label] for t in self.tracks],
                                       p.association_misses)
        for other in others:
            alive = [t for t in posterior if t.r > 0.0]
            posterior, _, _ = lmb_update(alive, other, self.ant, self.noise_std, self.log_kappa, self.rng,
                                         p.association, p.gibbs_samples, p.ranked_k, [ball[t.label] for t in alive],
                                         p.association_misses)
        kept = sorted((t for t in posterior if t.r >= p.prune), key=lambda t: -t.r)[: p.max_tracks]
        self.tracks = [self._resampled(replace(t, confirmed=t.confirmed or t.r > CONFIRM)) for t in kept]
        self._births = []
        for j, r_b in enumerate(birth_existences(r_U, p.birth_rate, p.birth_existence_max)):
            if r_b < p.prune:
                continue
            drawn = draw_birth(self.rng, scan, j, p.birth_particles, self.b, self.ant, self.noise_std, self.log_kappa)
            if drawn is not None:
                self._births.append(Track((self.step + 1, j), float(r_b), *drawn))
        self._predicted = False
        return self.estimates()

    def note_jamming(self, positions: np.ndarray, points: np.ndarray, levels_w: np.ndarray) -> None:
        """``filter.response``, after the step's update: each track counts the step as jammed
        when the team's cones deliver the threshold to at least half of its weight, and is
        downed after the response's steps in a row (:mod:`trackjam.estimation.failsafe`); a
        track not confirmed (r <= 0.5) starts over. Nothing without a response."""
        fs = self.p.response
        if fs is None:
            return
        self.tracks = [replace(t, watch=watched(t.watch, t.r > CONFIRM, lambda t=t: (t.X, t.log_w), positions, points,
                                                levels_w, self.ant, fs))
                       for t in self.tracks]

    def _resampled(self, t: Track) -> Track:
        n = self.p.particles if t.confirmed else min(self.p.birth_particles, self.p.particles)
        idx = kernel_systematic_indices(np.exp(t.log_w), n, self.rng.uniform())
        return replace(t, X=t.X[idx], log_w=np.full(n, -math.log(n)))

    def estimates(self) -> list[TrackEstimate]:
        """Every track's label, existence and particle moments, most likely first."""
        out = []
        for t in sorted(self.tracks, key=lambda t: -t.r):
            mean, cov = weighted_moments(t.X, np.exp(t.log_w))
            out.append(TrackEstimate(t.label, t.r, mean, cov, t.nu))
        return out

    def reset_track(self, label: tuple[int, int], existence: float, mean: np.ndarray | None = None,
                    cov: np.ndarray | None = None) -> None:
        """Fusion feedback for one track, called after ``update()``: set its existence and, when
        a fused Gaussian is given, redraw its particles from N(mean, cov)."""
        for i, t in enumerate(self.tracks):
            if t.label != label:
                continue
            t = replace(t, r=float(np.clip(existence, 0.0, 1.0)))
            if mean is not None and cov is not None:
                lam, V = np.linalg.eigh(0.5 * (np.asarray(cov, float) + np.asarray(cov, float).T))
                n = self.p.particles
                X = np.asarray(mean, float) + self.rng.standard_normal((n, 6)) @ (V * np.sqrt(np.clip(lam, 0, None))).T
                t = replace(t, X=X, log_w=np.full(n, -math.log(n)))
                if t.watch.downed:  # the redrawn particles take the hedge's branches again
                    t = replace(t, watch=replace(t.watch, fresh=True))
            self.tracks[i] = t
            return
        raise KeyError(f"no track labelled {label}")
