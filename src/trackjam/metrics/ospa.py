"""OSPA of order p with cut-off c (Schuhmacher et al. 2008; Section VI) for at most one
target: the truth set and the estimate set are each empty or one position."""

from __future__ import annotations

import numpy as np

from trackjam.arguments import real, vector


def ospa(truth: np.ndarray | None, estimate: np.ndarray | None, c: float = 10.0, p: float = 2.0) -> float:
    """OSPA(p, c) between ``{truth}`` and ``{estimate}`` (positions (3,) or None; a longer state
vector's first three entries) [m].

    Both empty: 0. Exactly one empty: c (the cardinality penalty). Both present:
    ``(min(|x - x_hat|, c)^p)^(1/p) = min(|x - x_hat|, c)``; the order p only matters for
    larger sets, and is accepted for the general definition's sake.
    """
    # an empty array is not the empty set here (None is): zeros((0, 3)) against a position gave 0
    c = real("c", c, 0.0, above=True)
    real("p", p, 0.0, above=True)
    x = None if truth is None else vector("truth", truth, 3, at_least=True)
    y = None if estimate is None else vector("estimate", estimate, 3, at_least=True)
    if x is None and y is None:
        return 0.0
    if x is None or y is None:
        return c
    d = float(np.linalg.norm(x[:3] - y[:3]))
    return min(d, c)
