"""The constant-velocity motion model of Eq. (1), the one the truth, the filters and a coasted
track all follow: x_t = Phi x_{t-1} + Gamma nu, nu ~ N(0, Sigma_v), Sigma_v = accel_var I3.

The filters propagate their particles with the compiled twin
``trackjam.estimation.kernels.kernel_cv_predict``, held to :func:`cv_matrices` by the tests.
"""

from __future__ import annotations

import numpy as np


def cv_matrices(dt: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Phi and Gamma of Eq. (1) for the state [x, y, z, vx, vy, vz]."""
    I3 = np.eye(3)
    Phi = np.block([[I3, dt * I3], [np.zeros((3, 3)), I3]])
    Gamma = np.vstack([0.5 * dt**2 * I3, dt * I3])
    return Phi, Gamma


def cv_step(x: np.ndarray, rng: np.random.Generator, accel_var: float, dt: float = 1.0) -> np.ndarray:
    """One random step of Eq. (1). Works on (6,) or (n, 6)."""
    Phi, Gamma = cv_matrices(dt)
    x = np.asarray(x, dtype=float)
    nu = rng.normal(0.0, np.sqrt(accel_var), size=x.shape[:-1] + (3,))
    return x @ Phi.T + nu @ Gamma.T


def cv_coast(x: np.ndarray, P: np.ndarray, accel_var: float, steps: int, dt: float = 1.0
             ) -> tuple[np.ndarray, np.ndarray]:
    """A Gaussian (x, P) predicted ``steps`` steps by Eq. (1): x <- Phi x, P <- Phi P Phi' + Q,
    Q = accel_var Gamma Gamma'."""
    Phi, Gamma = cv_matrices(dt)
    Q = accel_var * Gamma @ Gamma.T
    for _ in range(steps):
        x, P = Phi @ x, Phi @ P @ Phi.T + Q
    return x, P
