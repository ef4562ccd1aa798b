"""The range-finder's measurement model (Eqs. 6-8): z = h(x, u) + w, with Poisson clutter
uniform over the measurement space.

z = [rho, azimuth, inclination]: azimuth = atan2(dy, dx) in (-pi, pi], inclination =
atan2(sqrt(dx^2 + dy^2), dz) in [0, pi]. Noise standard deviations are Sigma_w's diagonal.
Clutter is uniform over rho in [0, h_a / cos(theta_a / 2)], azimuth in (-pi, pi], inclination in
[0, pi]; its density is the reciprocal of that box's volume.
"""

from __future__ import annotations

import numpy as np

from trackjam.arguments import amounts, flags, numeric, points, real, shown, together
from trackjam.radio.antenna import AntennaModel, detection_probability, received_power


def wrap_angle(a):
    """Wrap angles to (-pi, pi]."""
    a = np.asarray(a, dtype=float)
    w = np.mod(a + np.pi, 2 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def h(x, u) -> np.ndarray:
    """Eq. (7): [rho, azimuth, inclination] of position ``x`` (..., 3), or of the position of
    state ``x`` (..., 6), seen from ``u`` (..., 3); finite, of shapes that broadcast."""
    x, u = points("x", x, (3, 6), position_only=True), points("u", u)
    together(dict(x=x.shape, u=u.shape), x=x.shape[:-1], u=u.shape[:-1])
    return _h(x, u)


def _h(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """:func:`h` of float arrays its callers checked (the scans: the engine's per-step path)."""
    d = x[..., :3] - u
    rho = np.linalg.norm(d, axis=-1)
    az = np.arctan2(d[..., 1], d[..., 0])
    inc = np.arctan2(np.hypot(d[..., 0], d[..., 1]), d[..., 2])
    return np.stack([rho, az, inc], axis=-1)


def h_inverse(z, u) -> np.ndarray:
    """Position whose measurement from ``u`` is ``z`` (inverse of :func:`h`): ``z`` (..., 3)
    finite with rho >= 0, ``u`` (..., 3) finite, of shapes that broadcast."""
    z, u = points("z", z), points("u", u)
    together(dict(z=z.shape, u=u.shape), z=z.shape[:-1], u=u.shape[:-1])
    if np.any(z[..., 0] < 0.0):
        raise ValueError(f"z: its range rho (first entry) must be >= 0, got {float(z[..., 0].min())!r}")
    rho, az, inc = z[..., 0], z[..., 1], z[..., 2]
    d = np.stack([rho * np.sin(inc) * np.cos(az), rho * np.sin(inc) * np.sin(az), rho * np.cos(inc)], axis=-1)
    return np.asarray(u, dtype=float) + d


def clutter_bounds(max_range: float) -> np.ndarray:
    """Rows [low, high] of the measurement space over which clutter is uniform."""
    return np.array([[0.0, max_range], [-np.pi, np.pi], [0.0, np.pi]])


def clutter_density(max_range: float) -> float:
    """p_c(y): the uniform clutter density over the measurement space [1 / (m rad^2)]."""
    return 1.0 / (max_range * 2 * np.pi * np.pi)


def sample_clutter(rng: np.random.Generator, rate: float, max_range: float) -> np.ndarray:
    """Poisson(``rate``) clutter points uniform over the measurement space, shape (n, 3)."""
    n = rng.poisson(rate)
    b = clutter_bounds(max_range)
    pts = rng.uniform(b[:, 0], b[:, 1], size=(n, 3))
    # azimuth on (-pi, pi]
    pts[:, 1] = np.where(pts[:, 1] == -np.pi, np.pi, pts[:, 1])
    return pts


CLUTTER_RATE_MAX = 1000.0  # the configuration's bound on clutter.rate


def _scan_arguments(rng, x, u, p_d, noise_std, clutter_rate, max_range) -> None:
    if not isinstance(rng, (np.random.Generator, np.random.RandomState)):
        raise TypeError(f"rng: expected a numpy Generator (numpy.random.default_rng(seed)) or RandomState, "
                        f"got {type(rng).__name__}")
    if x is not None:
        points("x", x, (3, 6), ndim=1, position_only=True)
    points("u", u, ndim=1)
    real("p_d", p_d, 0.0, 1.0)
    std = amounts("noise_std", noise_std)
    if std.ndim > 1 or std.size not in (1, 3) or np.any(std <= 0.0):
        raise ValueError(f"noise_std: expected one deviation > 0 or 3 of them, got {std.tolist()!r}")
    real("clutter_rate", clutter_rate, 0.0, CLUTTER_RATE_MAX)
    real("max_range", max_range, 0.0, above=True)


def sample_scan(
    rng: np.random.Generator,
    x: np.ndarray | None,
    u: np.ndarray,
    p_d: float,
    noise_std,
    clutter_rate: float,
    max_range: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One scan of one agent: a target measurement with probability ``p_d`` (when ``x`` is
    given: present and detectable) plus clutter. Returns ``(Z (m, 3), from_target (m,))``;
    the target's measurement, when there is one, comes first.

    The random draws happen in a fixed order whatever the outcome, so one seed gives one scan.
    ``x`` (3 or 6 entries, its position finite) and ``u`` (3) finite, ``p_d`` in [0, 1],
    ``noise_std`` 3 entries (or one for all) > 0, ``clutter_rate`` in [0, 1000] (the configuration's bound), ``max_range`` > 0: checked
    before any draw.
    """
    _scan_arguments(rng, x, u, p_d, noise_std, clutter_rate, max_range)
    detect_draw = rng.uniform()
    noise = rng.normal(0.0, 1.0, size=3) * np.asarray(noise_std, dtype=float)
    clutter = sample_clutter(rng, clutter_rate, max_range)
    rows = []
    if x is not None and detect_draw < p_d:
        z = _h(np.asarray(x, dtype=float), np.asarray(u, dtype=float)) + noise
        z[1] = wrap_angle(z[1])
        rows.append(z)
    from_target = np.zeros(len(rows) + len(clutter), dtype=bool)
    from_target[: len(rows)] = True
    Z = np.vstack(rows + [clutter]) if rows else clutter
    return Z.reshape(-1, 3), from_target


def _scan_multi_arguments(rng, X, u, p_d, noise_std, clutter_rate, max_range) -> list:
    """sample_scan's checks for K targets; returns the rows of ``X`` as a list."""
    if isinstance(X, np.ndarray):
        if X.ndim != 2:
            raise ValueError(f"X: expected rows of 3 or 6 entries (one per target), got shape {X.shape}")
        rows = list(X)
    elif isinstance(X, (list, tuple)):
        rows = list(X)
    else:
        raise TypeError(f"X: expected a list of rows (one per target, None where it is not there) or an array, "
                        f"got {type(X).__name__}")
    for i, row in enumerate(rows):
        if row is None:
            continue
        x = numeric(f"X[{i}]", row)
        if x.shape not in ((3,), (6,)):
            raise ValueError(f"X[{i}]: expected 3 or 6 entries (a position or a state), got shape {x.shape}")
        finite = np.isfinite(x[:3])
        if not (finite.all() or np.isnan(x[:3]).all()):
            raise ValueError(f"X[{i}]: a position must be finite, or all NaN where the target is not there, "
                             f"got {x[:3].tolist()!r}")
    _scan_arguments(rng, None, u, 0.0, noise_std, clutter_rate, max_range)
    probs = amounts("p_d", p_d, 0.0, 1.0)
    if probs.ndim > 1 or probs.size not in (1, len(rows)):
        raise ValueError(f"p_d: expected one probability or one per row of X ({len(rows)}), got shape {probs.shape}")
    return rows


def sample_scan_multi(
    rng: np.random.Generator,
    X,
    u: np.ndarray,
    p_d,
    noise_std,
    clutter_rate: float,
    max_range: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One scan of one agent with K targets (ours): each target whose row of ``X`` is given
    (a position; None or NaN: absent or undetectable) yields a measurement with its own
    probability ``p_d[k]``, independently, plus clutter. Returns ``(Z (m, 3), source (m,))``,
    ``source`` the target's index or -1 for clutter; target measurements come first, in target
    order.

    Draws in a fixed order whatever the outcome: K detection draws, K noise vectors, then the
    clutter, so that one target draws exactly what :func:`sample_scan` draws. The arguments are
    checked before any draw, as :func:`sample_scan`'s are: each row of ``X`` None or 3 or 6
    entries whose position is finite or all NaN, ``p_d`` one probability or one per row.
    """
    rows = _scan_multi_arguments(rng, X, u, p_d, noise_std, clutter_rate, max_range)
    X, k = rows, len(rows)
    p_d = np.broadcast_to(np.asarray(p_d, dtype=float), (k,))
    detect_draw = rng.uniform(size=k)
    noise = rng.normal(0.0, 1.0, size=(k, 3)) * np.asarray(noise_std, dtype=float)
    clutter = sample_clutter(rng, clutter_rate, max_range)
    rows, source = [], []
    for i in range(k):
        x = None if X[i] is None else np.asarray(X[i], dtype=float)
        if x is not None and np.all(np.isfinite(x[:3])) and detect_draw[i] < p_d[i]:
            z = _h(x, np.asarray(u, dtype=float)) + noise[i]
            z[1] = wrap_angle(z[1])
            rows.append(z)
            source.append(i)
    Z = np.vstack(rows + [clutter]) if rows else clutter
    return Z.reshape(-1, 3), np.array(source + [-1] * len(clutter), dtype=np.int64)


def _flags(name: str, value, k: int) -> np.ndarray:
    """``value`` as a bool vector of ``k`` entries: booleans, or the integers 0 and 1."""
    a = np.asarray(value)
    b = flags(a)  # an empty list (no target) is read as floats, and taken
    if b is None and a.dtype.kind not in "iu":
        raise TypeError(f"{name}: expected booleans (or 0 and 1), one per target, got {a.dtype} {shown(a)}")
    if b is None:
        raise ValueError(f"{name}: expected booleans (or 0 and 1), got {shown(a)}")
    if a.shape != (k,):
        raise ValueError(f"{name}: expected one entry per target ({k}), got shape {a.shape}")
    return b


def _exposure_arguments(X, exists, detectable, u, aim, level_w, ant):
    """target_exposure's arguments checked (the README's pieces used alone); changes no value."""
    if not isinstance(ant, AntennaModel):
        raise TypeError(f"ant: expected an AntennaModel, got {type(ant).__name__}")
    X = numeric("X", X)
    if X.ndim != 2 or X.shape[1] != 3:
        raise ValueError(f"X: expected rows of 3 entries (K, 3), one per target, got shape {X.shape}")
    k = len(X)
    exists, detectable = _flags("exists", exists, k), _flags("detectable", detectable, k)
    if not np.isfinite(X[exists]).all():
        raise ValueError("X: a present target's row (exists True) must be finite; an absent one's is not read")
    u, aim = points("u", u, ndim=2), points("aim", aim, ndim=2)
    n = len(u)
    if aim.shape != (n, 3):
        raise ValueError(f"aim: expected one aim per agent as u has ({n}, 3), got shape {aim.shape}")
    level = amounts("level_w", level_w, 0.0, ant.l_max)
    if level.shape != (n,):
        raise ValueError(f"level_w: expected one level per agent ({n}), got shape {level.shape}")
    return X, exists, detectable, u, aim, level


def target_exposure(
    X, exists, detectable, u: np.ndarray, aim: np.ndarray, level_w: np.ndarray, ant: AntennaModel
) -> tuple[np.ndarray, np.ndarray]:
    """What K targets get from N transmitting agents (ours), each ``(N, K)``: the power agent j
    puts on target k, Eq. (10) [W], 0 where the target is absent (an occluded one is still
    jammed), and agent j's detection probability of target k, Eq. (9), 0 where the target is
    absent or occluded. ``X`` (K, 3) true positions (rows of absent targets are not read);
    ``u``, ``aim`` (N, 3) positions and antenna aims [m]; ``level_w`` (N,) transmit powers [W].
    A target's column is what the one-target engine computes for it.

    Checked before any work: ``X`` (K, 3), finite on the rows of present targets (an absent
    one's may be NaN); ``exists`` and ``detectable`` K booleans (or 0 and 1); ``u`` and ``aim``
    finite (N, 3); ``level_w`` N levels in [0, l_max]. The swarm engine, whose arrays are built
    so, calls :func:`target_exposure_unchecked`; both give the same result."""
    return target_exposure_unchecked(*_exposure_arguments(X, exists, detectable, u, aim, level_w, ant), ant)


def target_exposure_unchecked(X, exists, detectable, u, aim, level_w, ant: AntennaModel) -> tuple[np.ndarray, np.ndarray]:
    """:func:`target_exposure` without the checks of its arguments: the engine's."""
    X = np.asarray(X, dtype=float).reshape(-1, 3)
    exists, detectable = np.asarray(exists, dtype=bool), np.asarray(detectable, dtype=bool)
    x = np.where(exists[:, None], X, 0.0)[None, :, :]
    u, aim = np.asarray(u, dtype=float)[:, None, :], np.asarray(aim, dtype=float)[:, None, :]
    level = np.asarray(level_w, dtype=float)[:, None]
    to_target = np.where(exists[None, :], received_power(x, u, aim, level, ant), 0.0)
    p_d = np.where((exists & detectable)[None, :], detection_probability(x, u, aim, level, ant), 0.0)
    return to_target, p_d
