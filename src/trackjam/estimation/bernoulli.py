"""The Bernoulli particle filter of one agent (Section V-A, after Ristic et al. 2013).

Prediction (printed in Section V-A):

    e_{t|t-1} = p_b (1 - e_{t-1}) + p_s e_{t-1}
    s_{t|t-1}(x) = q_{t|t-1}(x) + p_s e_{t-1} ∫ pi(x | x') s_{t-1}(x') dx' / e_{t|t-1},
    q_{t|t-1}(x) = p_b (1 - e_{t-1}) b_t(x) / e_{t|t-1}

so the predicted particle set is the ``n`` survivors moved by Eq. (1) with weight
``p_s e_{t-1} / e_{t|t-1}`` in all, and ``n_b`` birth particles with ``p_b (1 - e_{t-1}) /
e_{t|t-1}`` in all. Update:

    q_t = ∫ p_D s_{t|t-1} - sum_{y in Y_t} ∫ p_D g_t(y | x, u_t) s_{t|t-1} dx / (lambda_c p_c(y))
    e_t = (1 - q_t) e_{t|t-1} / (1 - e_{t|t-1} q_t)
    s_t(x) = [(1 - p_D) + p_D sum_y g_t(y | x, u_t) / (lambda_c p_c(y))] s_{t|t-1}(x) / (1 - q_t)

with ``p_D = p_D(x, u_t, l_t)`` of Eq. (9) per particle and ``g_t = N(y; h(x, u_t), Sigma_w)``
(angle residuals wrapped). With particle weights ``w_i`` and the bracket ``L_i``,
``1 - q_t = sum_i w_i L_i``; the update runs in the log domain and an empty scan is a real
update (every factor is ``1 - p_D``, so a miss lowers the existence).

Birth density b_t (``filter.birth``):

* ``uniform`` (the paper): position uniform in the area, velocity uniform in ±v_b per axis.
  Few of 2000 particles uniform over 10^6 m^3 land near a measurement, so (ours) the birth
  particles are drawn by importance sampling: a fraction ``proposal_fraction`` around the
  *current* scan's measurements (h^{-1}(y) plus a Gaussian twice as wide as the measurement
  noise mapped to Cartesian space, floor 0.5 m), the rest uniform in the area, and each is
  weighted by ``b(x) / proposal(x)`` (the deterministic-mixture density). The birth density is
  still exactly the paper's uniform b(x); only the Monte-Carlo error changes.
  ``birth_proposal="plain"`` draws all birth particles from b(x) itself.
* ``measurement`` (ours): b_t is a mixture of Gaussians around the previous scan's
  measurements (h^{-1}(y) plus the measurement noise mapped to Cartesian space), velocity
  uniform in ±v_b, moved one step by Eq. (1)'s mean; uniform when the previous scan was empty.

The filter starts with ``e_0 = 0`` (nothing is known) and its particles drawn from the uniform
birth density, so that ``reset_to`` or a later birth has something to work with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import expit

from trackjam.config import Scenario
from trackjam.estimation.kernels import (
    kernel_cv_predict,
    kernel_reflect,
    kernel_log_gaussian_mixture,
    kernel_logsumexp,
    kernel_systematic_indices,
    kernel_update_factors,
    kernel_weighted_moments,
)
from trackjam.radio.antenna import AntennaModel, axis_of
from trackjam.radio.measurement import clutter_density, h_inverse

DT = 1.0  # dT [s], MODEL.md
PROPOSAL_INFLATE = 2.0  # importance proposal: width relative to the measurement noise (ours)
PROPOSAL_FLOOR = 0.5  # importance proposal: smallest standard deviation per axis [m] (ours)


@dataclass(frozen=True)
class Estimate:
    """What an agent reports: existence probability e, particle mean and covariance of s."""

    existence: float
    mean: np.ndarray  # (6,) [x, y, z, vx, vy, vz]
    cov: np.ndarray  # (6, 6)


def weighted_moments(X: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of particles ``X`` (n, d) with normalised weights ``w`` (n,)."""
    return kernel_weighted_moments(np.ascontiguousarray(X), np.ascontiguousarray(w, dtype=float))


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


def bernoulli_update(e_pred, X, log_w, Z, u, aim, level_w, ant: AntennaModel, noise_std, log_lambda_c):
    """The update of Section V-A on a weighted particle set (``log_w`` normalised).

    Returns ``(e_t, log_w_t, log(1 - q_t), log_L)``: the posterior existence, the posterior
    log-weights (normalised), the log of ``1 - q_t = sum_i w_i L_i`` and the per-particle
    ``log L_i``.
    """
    p_d_scale = max(float(level_w), 0.0) / ant.l_max * ant.p_d_max
    axis = axis_of(np.asarray(u, dtype=float), np.asarray(aim, dtype=float))
    _, log_L = kernel_update_factors(
        X, Z, np.asarray(u, dtype=float), axis, p_d_scale, ant.height, ant.tan_half, ant.r0, ant.n_e,
        np.asarray(noise_std, dtype=float), float(log_lambda_c),
    )
    log_joint = log_w + log_L
    log_A = float(kernel_logsumexp(log_joint))
    e = posterior_existence(e_pred, log_A)
    log_post = log_w if log_A == -np.inf else log_joint - log_A
    return e, log_post, log_A, log_L


def measurement_covariances(Z: np.ndarray, u: np.ndarray, noise_std, inflate: float, floor: float):
    """Cartesian Gaussians of the measurements: means h^{-1}(y, u) and covariances
    ``inflate^2 J diag(sigma^2) J^T + floor^2 I``, J the Jacobian of h^{-1} at y."""
    rho, az, inc = Z[:, 0], Z[:, 1], Z[:, 2]
    si, ci, sa, ca = np.sin(inc), np.cos(inc), np.sin(az), np.cos(az)
    J = np.empty((len(Z), 3, 3))
    J[:, :, 0] = np.stack([si * ca, si * sa, ci], axis=-1)
    J[:, :, 1] = np.stack([-rho * si * sa, rho * si * ca, np.zeros_like(rho)], axis=-1)
    J[:, :, 2] = np.stack([rho * ci * ca, rho * ci * sa, -rho * si], axis=-1)
    S = np.asarray(noise_std, dtype=float) ** 2
    cov = inflate**2 * (J * S) @ J.transpose(0, 2, 1) + floor**2 * np.eye(3)
    return h_inverse(Z, u), cov


def log_gaussian_mixture(P: np.ndarray, mu: np.ndarray, chol: np.ndarray) -> np.ndarray:
    """log of (1/k) sum_j N(p; mu_j, L_j L_j^T) at each row of ``P`` (n, 3)."""
    log_det = np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)
    d = np.ascontiguousarray(P[:, None, :] - mu[None, :, :])
    return kernel_log_gaussian_mixture(d, np.linalg.inv(chol), log_det)


class BernoulliFilter:
    """One agent's Bernoulli particle filter. Call ``predict()`` then ``update(...)`` each step."""

    def __init__(
        self,
        scenario: Scenario,
        rng: np.random.Generator,
        *,
        existence: float = 0.0,
        birth_proposal: str = "importance",
        proposal_fraction: float = 0.5,
    ):
        if birth_proposal not in ("importance", "plain"):
            raise ValueError(f"birth_proposal must be 'importance' or 'plain', got {birth_proposal!r}")
        if not 0.0 <= proposal_fraction <= 1.0:
            raise ValueError("proposal_fraction must lie in [0, 1]")
        f = scenario.filter
        self.rng = rng
        self.p_b = float(f.birth_prob)
        self.p_s = float(f.survival_prob)
        self.n = int(f.particles)
        self.n_b = int(f.birth_particles)
        self.birth = f.birth
        self.v_b = float(f.birth_speed)
        self.accel_var = scenario.filter_accel_var
        self.ant = AntennaModel.from_scenario(scenario)
        self.noise_std = np.asarray(scenario.sensor.noise_std, dtype=float)
        self.lambda_c = float(scenario.sensor.clutter_rate)
        # lambda_c = 0 would make g / (lambda_c p_c) infinite; a tiny floor keeps logs finite
        self.log_lambda_c = math.log(max(self.lambda_c * clutter_density(self.ant.max_range), 1e-300))
        self.walls = f.walls
        self.low = np.asarray(scenario.area.low, dtype=float)
        self.high = np.asarray(scenario.area.high, dtype=float)
        self.log_volume = float(np.sum(np.log(self.high - self.low)))
        self.importance = birth_proposal == "importance"
        self.proposal_fraction = float(proposal_fraction)

        self.e = float(np.clip(existence, 0.0, 1.0))
        self.X = self._uniform_states(self.n)
        self.log_w = np.full(self.n, -math.log(self.n))  # normalised log-weights of s_t
        self._e_pred: float | None = None  # set by predict(), consumed by update()
        self._w_surv = 1.0
        self._w_birth = 0.0
        self._birth: tuple[np.ndarray, np.ndarray] | None = None  # measurement birth drawn at predict
        self._prev_scan: tuple[np.ndarray, np.ndarray] | None = None  # (mu, cov) of the last scan
        mean, cov = weighted_moments(self.X, np.exp(self.log_w))
        self._last = Estimate(self.e, mean, cov)

    # -- birth density b_t ------------------------------------------------------------------
    def _uniform_states(self, k: int) -> np.ndarray:
        """``k`` draws of b(x): position uniform in the area, velocity uniform in ±v_b."""
        lo = np.concatenate([self.low, np.full(3, -self.v_b)])
        span = np.concatenate([self.high - self.low, np.full(3, 2.0 * self.v_b)])
        return lo + self.rng.random((k, 6)) * span

    def _uniform_birth_moments(self) -> tuple[np.ndarray, np.ndarray]:
        """Exact mean and covariance of the paper's uniform b(x)."""
        mean = np.concatenate([(self.low + self.high) / 2, np.zeros(3)])
        var = np.concatenate([(self.high - self.low) ** 2 / 12, np.full(3, self.v_b**2 / 3)])
        return mean, np.diag(var)

    def draw_uniform_birth(self, Z: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Birth particles of the uniform b(x) and their normalised log-weights b / proposal.

        Importance proposal (ours), a deterministic mixture with fixed counts: ``n_u``
        particles from b itself and ``n_p`` whose position is drawn from G, the mixture of the
        current scan's Cartesian Gaussians (velocity from b). The proposal density is
        ``(n_u / B) b(x) + (n_p / B) G(p) U(v)`` and the weight ``b(x) / proposal(x)``.
        """
        m = len(Z)
        B = self.n_b
        n_p = int(round(self.proposal_fraction * B)) if (self.importance and m > 0) else 0
        XB = self._uniform_states(B)
        if n_p == 0:
            return XB, np.full(B, -math.log(B))
        n_u = B - n_p
        mu, cov = measurement_covariances(Z, u, self.noise_std, PROPOSAL_INFLATE, PROPOSAL_FLOOR)
        chol = np.linalg.cholesky(cov)
        comp = self.rng.integers(m, size=n_p)
        xi = self.rng.standard_normal((n_p, 3))
        XB[n_u:, :3] = mu[comp] + (chol[comp] @ xi[:, :, None])[:, :, 0]
        P = XB[:, :3]
        inside = np.all((P >= self.low) & (P <= self.high), axis=1)
        # the velocity factor U(v) is common to b and to every proposal component: it cancels
        log_b = np.where(inside, -self.log_volume, -np.inf)
        log_q = np.logaddexp(
            log_b + math.log(n_u / B) if n_u else np.full(B, -np.inf),
            math.log(n_p / B) + log_gaussian_mixture(P, mu, chol),
        )
        log_iw = np.where(inside, log_b - log_q, -np.inf)
        if not np.any(inside):
            return self._uniform_states(B), np.full(B, -math.log(B))
        return XB, log_iw - kernel_logsumexp(log_iw)

    def _measurement_birth(self) -> tuple[np.ndarray, np.ndarray]:
        """Birth particles of the measurement-driven b_t (ours), equally weighted."""
        XB = self._uniform_states(self.n_b)
        if self._prev_scan is not None:
            mu, cov = self._prev_scan
            chol = np.linalg.cholesky(cov)
            comp = self.rng.integers(len(mu), size=self.n_b)
            xi = self.rng.standard_normal((self.n_b, 3))
            XB[:, :3] = mu[comp] + (chol[comp] @ xi[:, :, None])[:, :, 0] + DT * XB[:, 3:]
        return XB, np.full(self.n_b, -math.log(self.n_b))

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
        # Eq. (1): x_t = Phi x_{t-1} + Gamma nu, nu ~ N(0, accel_var I3)
        kernel_cv_predict(self.X, self.rng.standard_normal((self.n, 3)), DT, math.sqrt(self.accel_var))
        if self.walls == "reflect":
            kernel_reflect(self.X, self.low, self.high)
        X = self.X
        self._e_pred = e_pred

        m_s, C_s = weighted_moments(X, np.exp(self.log_w))
        if self.birth == "measurement":
            self._birth = self._measurement_birth()
            m_b, C_b = weighted_moments(self._birth[0], np.exp(self._birth[1]))
        else:
            self._birth = None
            m_b, C_b = self._uniform_birth_moments()
        mean, cov = mixture_moments([(self._w_surv, m_s, C_s), (self._w_birth, m_b, C_b)])
        self._last = Estimate(e_pred, mean, cov)
        return self._last

    def update(self, Z: np.ndarray, u: np.ndarray, aim: np.ndarray, level_w: float) -> Estimate:
        """Update of Section V-A with scan ``Z`` (m, 3) taken from ``u`` with the antenna aimed at
        ``aim`` and transmitting ``level_w`` watts; then systematic resampling to ``n`` particles.
        Runs ``predict()`` first if it was not called since the last update."""
        if self._e_pred is None:
            self.predict()
        e_pred = self._e_pred
        Z = np.asarray(Z, dtype=float).reshape(-1, 3)
        u = np.asarray(u, dtype=float)
        if self._birth is not None:
            XB, log_wB = self._birth
        else:
            XB, log_wB = self.draw_uniform_birth(Z, u)
        X = np.vstack([self.X, XB])
        with np.errstate(divide="ignore"):
            log_w = np.concatenate(
                [(math.log(self._w_surv) if self._w_surv > 0 else -np.inf) + self.log_w,
                 (math.log(self._w_birth) if self._w_birth > 0 else -np.inf) + log_wB]
            )
        e, log_post, _, log_L = bernoulli_update(
            e_pred, X, log_w, Z, u, aim, level_w, self.ant, self.noise_std, self.log_lambda_c
        )
        w = np.exp(log_post)
        w /= w.sum()
        mean, cov = weighted_moments(X, w)
        self.X, self.log_w = self._resample(X, w, log_L > 0.0)
        self.e = e
        self._e_pred = None
        self._birth = None
        if self.birth == "measurement":
            self._prev_scan = measurement_covariances(Z, u, self.noise_std, 1.0, PROPOSAL_FLOOR) if len(Z) else None
        self._last = Estimate(e, mean, cov)
        return self._last

    def _resample(self, X: np.ndarray, w: np.ndarray, supported: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Systematic resampling of the ``n + n_b`` weighted particles back to ``n``.

        ``supported`` marks the particles the scan made more likely (L_i > 1: near a
        measurement). While a target is new, they carry well under 1% of the mass next to the
        diffuse "somewhere else in the area" part, so plain resampling keeps a few dozen of
        them, too few to find the velocity, unobserved at a first detection. When their share
        would give them fewer than ``min(n_b, n / 5)`` slots, the two parts are resampled
        separately (ours): the supported part gets that many slots, the rest the others, each
        slot weighted by its part's mass over its slot count. The weighted set represents the
        same density; once the target is tracked the supported part dominates and this is
        plain systematic resampling.
        """
        n = self.n
        reserve = min(self.n_b, n // 5)
        W_a = float(w[supported].sum())
        W_r = float(w[~supported].sum())
        if reserve == 0 or W_a <= 0.0 or W_r <= 0.0 or W_a * n >= reserve:
            idx = kernel_systematic_indices(w, n, self.rng.uniform())
            return X[idx], np.full(n, -math.log(n))
        ia = np.flatnonzero(supported)
        ir = np.flatnonzero(~supported)
        n_r = n - reserve
        idx_a = ia[kernel_systematic_indices(w[ia] / W_a, reserve, self.rng.uniform())]
        idx_r = ir[kernel_systematic_indices(w[ir] / W_r, n_r, self.rng.uniform())]
        log_w = np.concatenate([np.full(reserve, math.log(W_a / reserve)), np.full(n_r, math.log(W_r / n_r))])
        return X[np.concatenate([idx_a, idx_r])], log_w

    def estimate(self) -> Estimate:
        """The latest estimate: predicted after ``predict()``, posterior after ``update()``."""
        return self._last

    def reset_to(self, existence: float, mean: np.ndarray | None = None, cov: np.ndarray | None = None) -> None:
        """Fusion feedback (end of Section V-A), called after ``update()``: set the existence;
        when a fused Gaussian is given, redraw the particles from N(mean, cov) (equal weights;
        a singular covariance is allowed)."""
        self.e = float(np.clip(existence, 0.0, 1.0))
        if mean is not None and cov is not None:
            mean = np.asarray(mean, dtype=float)
            cov = np.asarray(cov, dtype=float)
            lam, V = np.linalg.eigh(0.5 * (cov + cov.T))
            root = V * np.sqrt(np.clip(lam, 0.0, None))
            self.X = mean + self.rng.standard_normal((self.n, 6)) @ root.T
            self.log_w = np.full(self.n, -math.log(self.n))
            self._last = Estimate(self.e, mean.copy(), cov.copy())
        else:
            self._last = Estimate(self.e, self._last.mean, self._last.cov)

    @property
    def particles(self) -> np.ndarray:
        """The particles of s_t after the last update, (n, 6); weights ``exp(log_w)``."""
        return self.X
