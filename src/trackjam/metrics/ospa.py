"""OSPA of order p with cut-off c (Schuhmacher et al. 2008; Section VI) for at most one
target: the truth set and the estimate set are each empty or one position."""

from __future__ import annotations

import numpy as np


def ospa(truth: np.ndarray | None, estimate: np.ndarray | None, c: float = 10.0, p: float = 2.0) -> float:
    """OSPA(p, c) between ``{truth}`` and ``{estimate}`` (positions (3,) or None) [m].

    Both empty: 0. Exactly one empty: c (the cardinality penalty). Both present:
    ``(min(|x - x_hat|, c)^p)^(1/p) = min(|x - x_hat|, c)``; the order p only matters for
    larger sets, and is accepted for the general definition's sake.
    """
    if c <= 0 or p <= 0:
        raise ValueError("OSPA needs c > 0 and p > 0")
    if truth is None and estimate is None:
        return 0.0
    if truth is None or estimate is None:
        return float(c)
    d = float(np.linalg.norm(np.asarray(truth, dtype=float)[:3] - np.asarray(estimate, dtype=float)[:3]))
    return min(d, float(c))
