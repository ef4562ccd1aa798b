"""Birth densities b_t of the Bernoulli filter and the importance proposals that sample them.

The paper's b_t is uniform: position in the area, velocity uniform in ±v_b per axis. Few of
2000 particles drawn from it land near a measurement, so (ours) the filter samples it by
importance: the densities below are unchanged, only the Monte Carlo error is.

* :func:`draw_uniform_birth`: a deterministic mixture with fixed counts, ``n_u`` particles from
  b itself and ``n_p`` whose position comes from G, the mixture of the current scan's Cartesian
  Gaussians (h^{-1}(y) plus a Gaussian ``PROPOSAL_INFLATE`` times as wide as the measurement
  noise, floor ``PROPOSAL_FLOOR``); each particle is weighted by ``b(x) / q(x)`` with
  ``q = (n_u / B) b + (n_p / B) G U(v)``.
* :func:`redraw_young` (the two-scan proposal): the targets born one step ago, whose density is
  ``b(x_{t-1}) L_{t-1}(x_{t-1})`` moved by Eq. (1), are drawn again once scan t is in: position
  at t-1 from the proposal above built on scan t-1, velocity mostly from Gaussians that carry
  that position onto one of scan t's measurements in one step. Their velocity is what a first
  detection cannot tell and a second one pins down; drawn blindly, only the ~1 % of them whose
  velocity agrees with the second detection survive it, which is where a filter at 10k particles
  loses young tracks that a 50k one keeps.
* measurement-driven birth (ours, :func:`draw_measurement_birth`): b_t itself is a mixture of
  Gaussians around the previous scan's measurements, velocity uniform in ±v_m, moved one step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from trackjam.estimation.kernels import (
    kernel_gaussian_sample,
    kernel_log_gaussian_mixture,
    kernel_logsumexp,
    kernel_position_proposal,
    kernel_two_scan_velocity,
    kernel_young_weights,
)

DT = 1.0  # dT [s]
PROPOSAL_INFLATE = 2.0  # importance proposal: width relative to the measurement noise (ours)
PROPOSAL_FLOOR = 0.5  # importance proposal: smallest standard deviation per axis [m] (ours)
YOUNG_BLIND_SHARE = 0.1  # two-scan proposal: share of velocities drawn from b's U(±v_b) itself (ours)
# two-scan proposal: narrower Gaussians, since its weight spans six dimensions (ours)
YOUNG_INFLATE = 1.3
YOUNG_FLOOR = 0.1


def measurement_covariances(Z: np.ndarray, u: np.ndarray, noise_std, inflate: float, floor: float):
    """Cartesian Gaussians of the measurements: means h^{-1}(y, u) and covariances
    ``inflate^2 J diag(sigma^2) J^T + floor^2 I``, J the Jacobian of h^{-1} at y."""
    rho, az, inc = Z[:, 0], Z[:, 1], Z[:, 2]
    si, ci, sa, ca = np.sin(inc), np.cos(inc), np.sin(az), np.cos(az)
    J = np.zeros((len(Z), 3, 3))
    J[:, 0, 0], J[:, 1, 0], J[:, 2, 0] = si * ca, si * sa, ci
    J[:, 0, 1], J[:, 1, 1] = -rho * si * sa, rho * si * ca
    J[:, 0, 2], J[:, 1, 2], J[:, 2, 2] = rho * ci * ca, rho * ci * sa, -rho * si
    S = np.asarray(noise_std, dtype=float) ** 2
    cov = inflate**2 * (J * S) @ J.transpose(0, 2, 1) + floor**2 * np.eye(3)
    mu = np.empty((len(Z), 3))
    mu[:, 0], mu[:, 1], mu[:, 2] = u[0] + rho * si * ca, u[1] + rho * si * sa, u[2] + rho * ci
    return mu, cov


@dataclass(frozen=True)
class Gaussians:
    """An equally weighted mixture of k Gaussians in R^3: means ``mu`` (k, 3), Cholesky factors
    ``chol`` (k, 3, 3)."""

    mu: np.ndarray
    chol: np.ndarray

    @classmethod
    def of(cls, mu: np.ndarray, cov: np.ndarray) -> "Gaussians":
        return cls(np.asarray(mu, dtype=float), np.linalg.cholesky(cov))

    @classmethod
    def of_scan(cls, Z: np.ndarray, u: np.ndarray, noise_std, inflate: float = PROPOSAL_INFLATE,
                floor: float = PROPOSAL_FLOOR) -> "Gaussians":
        return cls.of(*measurement_covariances(Z, u, noise_std, inflate, floor))

    def draws(self, rng: np.random.Generator, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The random numbers of :meth:`sample`: each draw's component and its standard normals."""
        return rng.integers(len(self.mu), size=k), rng.standard_normal((k, 3))

    def sample(self, rng: np.random.Generator, k: int) -> np.ndarray:
        return kernel_gaussian_sample(self.mu, self.chol, *self.draws(rng, k))

    def inverse(self) -> tuple[np.ndarray, np.ndarray]:
        """The inverse Cholesky factors and ``log det`` of each, as :meth:`log_pdf` takes them."""
        return np.linalg.inv(self.chol), np.log(np.diagonal(self.chol, axis1=1, axis2=2)).sum(axis=1)

    def log_pdf(self, P: np.ndarray) -> np.ndarray:
        """log of (1/k) sum_j N(p_i; mu_j, C_j) at each row of ``P`` (n, 3)."""
        Linv, log_det = self.inverse()
        return kernel_log_gaussian_mixture(np.ascontiguousarray(P), self.mu, Linv, log_det)


def _read_only(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    for a in arrays:
        a.flags.writeable = False
    return arrays


@dataclass(frozen=True)
class UniformBirth:
    """The paper's b(x): position uniform in the box [low, high], velocity uniform in ±v_b."""

    low: np.ndarray
    high: np.ndarray
    v_b: float

    @property
    def log_volume(self) -> float:
        return float(np.sum(np.log(self.high - self.low)))

    def box(self, v_b: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The state box's lowest corner and its widths, velocity in ±``v_b`` (default b's); b's
        own is built once (read-only arrays)."""
        if v_b is None:
            if "_box" not in self.__dict__:
                object.__setattr__(self, "_box", _read_only(*self._make_box(self.v_b)))
            return self.__dict__["_box"]
        return self._make_box(v_b)

    def _make_box(self, v: float) -> tuple[np.ndarray, np.ndarray]:
        return (np.concatenate([self.low, np.full(3, -v)]),
                np.concatenate([self.high - self.low, np.full(3, 2.0 * v)]))

    def draw(self, rng: np.random.Generator, k: int, v_b: float | None = None) -> np.ndarray:
        lo, span = self.box(v_b)
        X = rng.random((k, 6))
        X *= span
        X += lo  # lo + r span, in place
        return X

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        """Exact mean and covariance of b (computed once; read-only arrays)."""
        if "_moments" not in self.__dict__:
            mean = np.concatenate([(self.low + self.high) / 2, np.zeros(3)])
            var = np.concatenate([(self.high - self.low) ** 2 / 12, np.full(3, self.v_b**2 / 3)])
            object.__setattr__(self, "_moments", _read_only(mean, np.diag(var)))
        return self.__dict__["_moments"]

    def in_area(self, P: np.ndarray) -> np.ndarray:
        return np.all((P >= self.low) & (P <= self.high), axis=1)


def _normalised(log_w: np.ndarray) -> np.ndarray:
    return log_w - kernel_logsumexp(log_w)


def _position_proposal(rng, b: UniformBirth, G: Gaussians | None, k: int, fraction: float):
    """``k`` states whose velocity is b's and whose position comes from the deterministic mixture
    (n_u from the area, n_p from G); returns them with ``log q_p(p) - log U_area(p)``, -inf
    outside the area (where b is 0)."""
    n_p = int(round(fraction * k)) if G is not None else 0
    if n_p == 0:
        return b.draw(rng, k), np.zeros(k)
    X = rng.random((k, 6))  # b.draw's numbers, scaled to b's box by the kernel
    n_u = k - n_p
    comp, xi = G.draws(rng, n_p)
    # rows n_u: take G's draws; log q = logaddexp(log(n_u / k), log(n_p / k) + log G(p) + log |area|)
    # (G relative to the uniform density of the area), +inf where a row drawn from G lies outside
    # the area (the rows drawn from b are inside by construction); one compiled pass
    log_q = kernel_position_proposal(X, *b.box(), n_u, G.mu, G.chol, comp, xi, *G.inverse(), b.log_volume,
                                     math.log(n_u / k) if n_u else -np.inf, math.log(n_p / k), b.low, b.high)
    return X, log_q


def draw_uniform_birth(rng, b: UniformBirth, G: Gaussians | None, k: int, fraction: float):
    """``k`` particles of the uniform b and their normalised log-weights ``b / q``. With no scan
    Gaussians (an empty scan, or plain sampling) the particles are b's own, equally weighted."""
    X, log_q = _position_proposal(rng, b, G, k, fraction)
    log_w = -log_q  # b / q with b's constant cancelled; -inf outside the area
    if not np.any(np.isfinite(log_w)):
        return b.draw(rng, k), np.full(k, -math.log(k))
    return X, _normalised(log_w)


def redraw_young(rng, b: UniformBirth, G_prev: Gaussians, G_now: Gaussians, k: int, fraction: float,
                 accel_var: float, log_L_prev) -> tuple[np.ndarray, np.ndarray]:
    """The two-scan proposal: ``k`` states at t-1 of the component ``b(x) L_{t-1}(x)`` and their
    normalised log-weights, to be moved by Eq. (1) to t.

    Position p from the proposal of :func:`draw_uniform_birth` on scan t-1 (``G_prev``). Velocity:
    the measurements j of scan t (``G_now``) that p can reach in one step within b's velocity box
    (each axis of ``mu_j - p`` within ``v_b dT`` plus three standard deviations) are p's
    *reachable* ones; with probability ``YOUNG_BLIND_SHARE``, or when none is reachable, v comes
    from U(±v_b), otherwise from ``N((mu_j - p) / dT, C_j / dT^2 + accel_var / 4 I)`` for a reachable
    j chosen uniformly: the velocity that carries p onto that measurement. Weight
    ``b(p, v) L_{t-1}(p) / (q_p(p) q_v(v | p))``, q_v the whole mixture at every particle.
    ``log_L_prev(X)`` gives log L_{t-1} of Section V-A's update at t-1.
    """
    X, log_qp = _position_proposal(rng, b, G_prev, k, fraction)
    cov_v = G_now.chol @ G_now.chol.transpose(0, 2, 1) / DT**2 + (accel_var / 4.0) * np.eye(3)
    chol_v = np.linalg.cholesky(cov_v)
    V = np.ascontiguousarray(X[:, 3:])
    log_qv = kernel_two_scan_velocity(
        np.ascontiguousarray(X[:, :3]), V, G_now.mu, chol_v, np.linalg.inv(chol_v),
        np.log(np.diagonal(chol_v, axis1=1, axis2=2)).sum(axis=1), np.sqrt(np.diagonal(cov_v, axis1=1, axis2=2)),
        b.v_b, DT, YOUNG_BLIND_SHARE, rng.random(k), rng.random(k), rng.standard_normal((k, 3)),
    )
    X[:, 3:] = V
    log_U = -3.0 * math.log(2.0 * b.v_b)
    # log_U + log L_{t-1} - log q_p - log q_v where V lies in b's box and q_p is finite, else -inf
    log_w = kernel_young_weights(V, b.v_b, log_U, log_L_prev(X), log_qp, log_qv)
    if not np.any(np.isfinite(log_w)):
        return X, np.full(k, -np.inf)
    return X, _normalised(log_w)


MEASUREMENT_BIRTH_ROUNDS = 20  # measurement-driven birth: redraws of the particles that left the area


def draw_measurement_birth(rng, b: UniformBirth, G_prev: Gaussians | None, k: int, speed: float):
    """``k`` equally weighted particles of the measurement-driven b_t (ours): position from the
    previous scan's Gaussians, velocity uniform in ±``speed``, moved one step by Eq. (1)'s mean,
    truncated to the area (no target is outside it): a particle that lands outside is drawn again,
    up to ``MEASUREMENT_BIRTH_ROUNDS`` times, then its position is drawn uniformly in the area, its
    velocity still uniform in ±``speed`` (not b's ±v_b), as are all of them when the previous scan
    held only points whose Gaussians lie outside the area. When the previous scan was empty the
    particles are b's own draws (velocity in ±v_b)."""
    if G_prev is None:
        return b.draw(rng, k), np.full(k, -math.log(k))

    def moved(m: int) -> np.ndarray:
        Y = b.draw(rng, m, v_b=speed)
        Y[:, :3] = G_prev.sample(rng, m) + DT * Y[:, 3:]
        return Y

    X = moved(k)
    out = ~b.in_area(X[:, :3])
    for _ in range(MEASUREMENT_BIRTH_ROUNDS):
        if not out.any():
            break
        X[out] = moved(int(out.sum()))
        out = ~b.in_area(X[:, :3])
    if out.any():
        X[out] = b.draw(rng, int(out.sum()), v_b=speed)
    return X, np.full(k, -math.log(k))
