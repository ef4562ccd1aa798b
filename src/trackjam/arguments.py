"""Checks of the arguments of the library's pieces used alone (the README's "The pieces are
usable alone"): one ValueError or TypeError naming the argument and the problem, before any
work. A configuration is checked by its own schema (:mod:`trackjam.config`), whose bounds these
repeat where both meet; these catch what a caller builds by hand. Without them a kernel read
past the end of a short array, a NaN became a detection probability of 0, and a sample count
of 10^12 ran a compiled loop that no Ctrl-C stops."""

from __future__ import annotations

import math
import numbers
import os

import numpy as np

from trackjam.errors import bounded_repr


def whole(name: str, value, low: int, high: int) -> int:
    """``value`` as an int in [low, high]: an integer (numpy's too), not a bool or a float."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: expected a whole number in [{low}, {high}], got {type(value).__name__} {value!r:.40}")
    if not low <= value <= high:
        raise ValueError(f"{name}: must lie in [{low}, {high}], got {value}")
    return int(value)


def interval(low: float, high: float, above: bool = False) -> str:
    """[low, high] as text; an open end where it is excluded (``above``) or infinite."""
    return f"{'(' if above or low == -math.inf else '['}{low:g}, {high:g}{']' if high < math.inf else ')'}"


def real(name: str, value, low: float = -math.inf, high: float = math.inf, *, above: bool = False) -> float:
    """``value`` as a finite float in [low, high] (in (low, high] with ``above``): a real number
    (numpy's too, or a 0-d array of one), not a bool."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value.item()
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__} {value!r:.40}")
    v = float(value)
    if not math.isfinite(v) or v > high or v < low or (above and v <= low):
        raise ValueError(f"{name}: must be a finite number in {interval(low, high, above)}, got {v!r}")
    return v


def vector(name: str, value, size: int | None = 3, *, at_least: bool = False) -> np.ndarray:
    """``value`` as a finite float array of one dimension, of ``size`` entries (at least
    ``size`` with ``at_least``; any with None)."""
    a = numeric(name, value)
    n = a.shape[0] if a.ndim == 1 else -1
    if a.ndim != 1 or (size is not None and (n < size if at_least else n != size)):
        want = "any number of" if size is None else f"{'at least ' if at_least else ''}{size}"
        raise ValueError(f"{name}: expected a vector of {want} entries, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be finite, got {a.tolist()!r:.60}")
    return a


def corners(low, high, *, scalars: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """An area's corners ``low`` and ``high``: finite 3-vectors (or, with ``scalars``, numbers
    that stand for all three), low below high on every axis."""
    if scalars:
        low, high = (np.full(3, real(k, a)) if (a := numeric(k, v)).ndim == 0 else a for k, v in (("low", low), ("high", high)))
    lo, hi = vector("low", low), vector("high", high)
    if np.any(lo >= hi):
        raise ValueError(f"low, high: the area's low corner must lie below its high one, got {lo.tolist()} and {hi.tolist()}")
    return lo, hi


def numeric(name: str, value) -> np.ndarray:
    """``value`` as a float array: numbers only (not bools, complex numbers or texts)."""
    try:
        a = np.asarray(value)
        if isinstance(value, (list, tuple)) and a.dtype.kind in "iuf":  # numpy reads [1.0, True] as numbers
            if any(isinstance(v, (bool, np.bool_)) for v in np.asarray(value, dtype=object).ravel()):
                raise TypeError(f"{name}: expected numbers, got a bool among them: {shown(value)}")
    except ValueError:  # a ragged list
        raise TypeError(f"{name}: expected numbers in a regular array, got {type(value).__name__} {shown(value)}") from None
    if a.dtype.kind not in "iuf":
        try:
            if a.dtype.kind != "O":
                raise TypeError
            if any(isinstance(v, (bool, np.bool_, str, bytes, complex, np.complexfloating)) for v in a.ravel()):
                raise TypeError
            return a.astype(float)
        except (TypeError, ValueError):
            raise TypeError(f"{name}: expected numbers, got {type(value).__name__} {shown(value)}") from None
    return a.astype(float, copy=False)


def shown(value) -> str:
    """``value`` (an array as its list) as it is written, cut to 40 characters, for a message."""
    return bounded_repr(value.tolist() if isinstance(value, np.ndarray) else value, 40)


def points(name: str, value, sizes: tuple[int, ...] = (3,), *, ndim: int | None = None,
           position_only: bool = False) -> np.ndarray:
    """``value`` as a finite float array whose last axis holds one of ``sizes`` entries (a
    position: 3; a position or a state: (3, 6)), of ``ndim`` dimensions when given; with
    ``position_only`` only the first three entries (the position of a state) must be finite."""
    a = numeric(name, value)
    if a.ndim == 0 or a.shape[-1] not in sizes or (ndim is not None and a.ndim != ndim):
        last = " or ".join(str(s) for s in sizes)
        rows = {1: "a vector", 2: "rows"}.get(ndim, "an array")
        raise ValueError(f"{name}: expected {rows} of {last} entries (one per coordinate on the last axis), got shape {a.shape}")
    if not np.all(np.isfinite(a[..., :3] if position_only else a)):
        raise ValueError(f"{name}: must be finite, got {'NaN' if np.any(np.isnan(a)) else 'an infinite value'}")
    return a


def flags(value) -> np.ndarray | None:
    """``value`` as a bool array when it holds booleans or only the integers 0 and 1 (an empty
    array, of any kind, holds no entry to refuse); None otherwise, for the caller's message."""
    a = np.asarray(value)
    if a.dtype == bool or a.size == 0:
        return a.astype(bool, copy=False)
    if a.dtype.kind in "iu" and np.all((a == 0) | (a == 1)):
        return a.astype(bool)
    return None


def amounts(name: str, value, low: float = 0.0, high: float = math.inf) -> np.ndarray:
    """``value`` as a float array (any shape) of finite numbers in [low, high]."""
    a = numeric(name, value)
    bad = ~np.isfinite(a) | (a < low) | (a > high)
    if np.any(bad):
        raise ValueError(f"{name}: must be finite numbers in {interval(low, high)}, got {a[bad].ravel()[0]!r}")
    return a


BROADCAST_MAX = 10**8  # entries of the largest broadcast the per-call functions take (0.8 GB of floats)


def together(shown: dict[str, tuple[int, ...]] | None = None, **shapes: tuple[int, ...]) -> tuple[int, ...]:
    """The shape the named shapes broadcast to; a ValueError naming them when they do not, or
    when the broadcast would hold more than ``BROADCAST_MAX`` entries. ``shown``: the shapes
    the message gives (the arguments' own, where ``shapes`` leave out a coordinate axis)."""
    listed = ", ".join(f"{k} {v}" for k, v in (shown or shapes).items())
    try:
        shape = np.broadcast_shapes(*shapes.values())
    except ValueError:
        raise ValueError(f"{', '.join(shapes)}: shapes do not broadcast together: {listed}") from None
    if math.prod(shape) > BROADCAST_MAX:
        raise ValueError(f"{', '.join(shapes)}: together they make {math.prod(shape):,} entries (at most "
                         f"{BROADCAST_MAX:,}), too many to fit in memory: {listed}")
    return shape


def covariance(name: str, value, size: int) -> np.ndarray:
    """``value`` as a finite, symmetric, positive semi-definite (size, size) matrix (asymmetries
    up to 1e-6 of its largest entry and eigenvalues down to -1e-9 of it are rounding)."""
    C = numeric(name, value)
    if C.shape != (size, size):
        raise ValueError(f"{name}: expected a ({size}, {size}) matrix, got shape {C.shape}")
    if not np.all(np.isfinite(C)):
        raise ValueError(f"{name}: must be finite")
    scale = float(np.max(np.abs(C))) if C.size else 0.0
    if not np.allclose(C, C.T, rtol=1e-6, atol=1e-6 * scale):
        raise ValueError(f"{name}: must be symmetric")
    eig = np.linalg.eigvalsh(C)
    if eig[0] < -1e-9 * max(scale, 1e-300):
        raise ValueError(f"{name}: must be positive semi-definite, got an eigenvalue {eig[0]:.3g}")
    return C


def text_path(name: str, value, what: str = "a file's path") -> str:
    """``value``, a path given as text (a ``str`` or a path-like of one), as a ``str``. A path of
    bytes, another kind, an empty text and a NUL character (pathlib's "embedded null byte", from
    deep in the write) are refused naming ``name``."""
    path = os.fspath(value) if isinstance(value, (str, os.PathLike)) else None
    if not isinstance(path, str):
        raise TypeError(f"{name}: expected {what} as text, got {type(value).__name__} {shown(value)}")
    if not path:
        raise ValueError(f"{name}: expected {what}, got an empty text")
    if "\x00" in path:
        raise ValueError(f"{name}: holds a NUL character, which no path may: {shown(path)}")
    return path
