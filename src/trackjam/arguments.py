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
