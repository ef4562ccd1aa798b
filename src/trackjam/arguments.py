"""Checks of the arguments of the library's pieces used alone (the README's "The pieces are
usable alone"): one ValueError or TypeError naming the argument and the problem, before any
work. A configuration is checked by its own schema (:mod:`trackjam.config`), whose bounds these
repeat where both meet; these catch what a caller builds by hand. Without them a kernel read
past the end of a short array, a NaN became a detection probability of 0, and a sample count
of 10^12 ran a compiled loop that no Ctrl-C stops."""

from __future__ import annotations

import math
import numbers

import numpy as np


def whole(name: str, value, low: int, high: int) -> int:
    """``value`` as an int in [low, high]: an integer (numpy's too), not a bool or a float."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: expected a whole number in [{low}, {high}], got {type(value).__name__} {value!r:.40}")
    if not low <= value <= high:
        raise ValueError(f"{name}: must lie in [{low}, {high}], got {value}")
    return int(value)


def real(name: str, value, low: float = -math.inf, high: float = math.inf, *, above: bool = False) -> float:
    """``value`` as a finite float in [low, high] (in (low, high] with ``above``)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__} {value!r:.40}")
    v = float(value)
    if not math.isfinite(v) or v > high or v < low or (above and v <= low):
        where = f"({low:g}, {high:g}]" if above else f"[{low:g}, {high:g}]"
        raise ValueError(f"{name}: must be a finite number in {where}, got {v!r}")
    return v


def vector(name: str, value, size: int | None = 3, *, at_least: bool = False) -> np.ndarray:
    """``value`` as a finite float array of one dimension, of ``size`` entries (at least
    ``size`` with ``at_least``; any with None)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected numbers, got {type(value).__name__} {value!r:.40}") from None
    n = a.shape[0] if a.ndim == 1 else -1
    if a.ndim != 1 or (size is not None and (n < size if at_least else n != size)):
        want = "any number of" if size is None else f"{'at least ' if at_least else ''}{size}"
        raise ValueError(f"{name}: expected a vector of {want} entries, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be finite, got {a.tolist()!r:.60}")
    return a


def corners(low, high) -> tuple[np.ndarray, np.ndarray]:
    """An area's corners ``low`` and ``high``: finite 3-vectors, low below high on every axis."""
    lo, hi = vector("low", low), vector("high", high)
    if np.any(lo >= hi):
        raise ValueError(f"low, high: the area's low corner must lie below its high one, got {lo.tolist()} and {hi.tolist()}")
    return lo, hi


def _array(name: str, value) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected numbers, got {type(value).__name__} {value!r:.40}") from None
    return a


def points(name: str, value, sizes: tuple[int, ...] = (3,), *, ndim: int | None = None) -> np.ndarray:
    """``value`` as a finite float array whose last axis holds one of ``sizes`` entries (a
    position: 3; a position or a state: (3, 6)), of ``ndim`` dimensions when given."""
    a = _array(name, value)
    if a.ndim == 0 or a.shape[-1] not in sizes or (ndim is not None and a.ndim != ndim):
        last = " or ".join(str(s) for s in sizes)
        rows = {1: "a vector", 2: "rows"}.get(ndim, "an array")
        raise ValueError(f"{name}: expected {rows} of {last} entries (one per coordinate on the last axis), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be finite, got {'NaN' if np.any(np.isnan(a)) else 'an infinite value'}")
    return a


def amounts(name: str, value, low: float = 0.0, high: float = math.inf) -> np.ndarray:
    """``value`` as a float array (any shape) of finite numbers in [low, high]."""
    a = _array(name, value)
    bad = ~np.isfinite(a) | (a < low) | (a > high)
    if np.any(bad):
        raise ValueError(f"{name}: must be finite numbers in [{low:g}, {high:g}], got {a[bad].ravel()[0]!r}")
    return a


def together(**shapes: tuple[int, ...]) -> tuple[int, ...]:
    """The shape the named shapes broadcast to; a ValueError naming them when they do not."""
    try:
        return np.broadcast_shapes(*shapes.values())
    except ValueError:
        listed = ", ".join(f"{k} {v}" for k, v in shapes.items())
        raise ValueError(f"{', '.join(shapes)}: shapes do not broadcast together: {listed}") from None


def covariance(name: str, value, size: int) -> np.ndarray:
    """``value`` as a finite, symmetric, positive semi-definite (size, size) matrix (eigenvalues
    down to -1e-9 of the largest are rounding)."""
    C = _array(name, value)
    if C.shape != (size, size):
        raise ValueError(f"{name}: expected a ({size}, {size}) matrix, got shape {C.shape}")
    if not np.all(np.isfinite(C)):
        raise ValueError(f"{name}: must be finite")
    scale = float(np.max(np.abs(C))) if C.size else 0.0
    if not np.allclose(C, C.T, rtol=1e-8, atol=1e-12 * max(scale, 1.0)):
        raise ValueError(f"{name}: must be symmetric")
    eig = np.linalg.eigvalsh(C)
    if eig[0] < -1e-9 * max(scale, 1e-300):
        raise ValueError(f"{name}: must be positive semi-definite, got an eigenvalue {eig[0]:.3g}")
    return C
