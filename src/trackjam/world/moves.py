"""The pursuers' admissible displacements, Eq. (3), read as the model document (docs/model.md) fixes it.

Every radial step r in Delta_R, inclination phi = l2 * 2pi/N_phi (l2 = 0..N_phi) and azimuth
theta = l3 * 2pi/N_theta (l3 = 1..N_theta) gives r [sin phi cos theta, sin phi sin theta,
cos phi]; repeated vectors are counted once, and hovering (zero) is added as control 0.
The paper's default (Delta_R = [1, 3, 5], N_phi = N_theta = 8) gives 79 controls; one step of
3 m with N_phi = 4, N_theta = 8 gives Table I's 11.
"""

from __future__ import annotations

import numpy as np

from trackjam.arguments import vector, whole


def displacement_set(radial_steps, n_inclination: int, n_azimuth: int) -> np.ndarray:
    """The admissible displacements, shape (K, 3), hover first, then in Eq. (3)'s loop order."""
    # the configuration's bounds: 10**6 directions ran for minutes, NaN steps gave NaN moves
    n_inclination = whole("n_inclination", n_inclination, 1, 360)
    n_azimuth = whole("n_azimuth", n_azimuth, 1, 360)
    steps = vector("radial_steps", radial_steps, None)
    if steps.size == 0 or np.any(steps <= 0) or np.any(steps > 1e4) or steps.size > 32:
        raise ValueError(f"radial_steps: expected 1 to 32 step lengths in (0, 10000] m, got {steps.tolist()!r:.60}")
    radial_steps = steps.tolist()
    out = [np.zeros(3)]
    seen = {(0.0, 0.0, 0.0)}
    for r in radial_steps:
        for l2 in range(n_inclination + 1):
            phi = l2 * 2 * np.pi / n_inclination
            for l3 in range(1, n_azimuth + 1):
                theta = l3 * 2 * np.pi / n_azimuth
                v = r * np.array([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)])
                key = tuple(np.round(v, 9) + 0.0)
                if key not in seen:
                    seen.add(key)
                    out.append(v)
    return np.array(out)


def in_area(p, low, high) -> np.ndarray:
    """Whether positions lie in the closed box [low, high]."""
    p = np.asarray(p, dtype=float)
    eps = 1e-9
    return np.all((p >= np.asarray(low) - eps) & (p <= np.asarray(high) + eps), axis=-1)


def admissible_moves(u, displacements, low, high) -> np.ndarray:
    """Boolean mask of the displacements that keep an agent at ``u`` inside the area."""
    return in_area(np.asarray(u, dtype=float) + displacements, low, high)
