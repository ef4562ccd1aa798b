"""The actions a caller gives ``Simulation.step((moves, levels))``, checked before the step
changes anything: numpy would read a negative index from the end, truncate 1.7 to 1 and let a
move leave the area, silently."""

from __future__ import annotations

import numpy as np

from trackjam.errors import bounded_repr
from trackjam.world.moves import admissible_moves


def checked_actions(actions, positions: np.ndarray, displacements: np.ndarray, n_levels: int,
                    low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(moves, levels)`` as two int64 arrays of one index per agent, or a ValueError naming
    the argument: each move an index into Eq. (3)'s displacements that keeps its agent in the
    area (the model document: any other is not admissible), each level an index into L."""
    n = len(positions)
    if not isinstance(actions, (tuple, list, np.ndarray)) or len(actions) != 2:
        raise ValueError(f"actions: expected a pair (moves, levels) of {n} indices each, got {_shown(actions)}")
    out = []
    for name, given, size in (("moves", actions[0], len(displacements)), ("levels", actions[1], n_levels)):
        try:
            a = np.asarray(given)
        except (ValueError, TypeError):  # ragged nested lists
            a = np.asarray(None)
        if a.shape != (n,) or a.dtype.kind not in "iu" or has_bool(given):
            raise ValueError(f"actions: {name} must be {n} integers (one per agent), got {_shown(given)}")
        bad = np.flatnonzero((a < 0) | (a >= size))
        if bad.size:
            j = int(bad[0])
            raise ValueError(f"actions: {name}[{j}] = {a[j]} is not an index in [0, {size - 1}]")
        out.append(a.astype(np.int64))
    moves = out[0]
    for j in range(n):
        if not admissible_moves(positions[j], displacements[moves[j]: moves[j] + 1], low, high)[0]:
            raise ValueError(f"actions: moves[{j}] = {moves[j]} takes agent {j} out of the area (not admissible)")
    return moves, out[1]


def has_bool(given) -> bool:
    """A True or False among the entries (a 0-d array of one too): numpy reads [True, 0, 0] as
    the integers [1, 0, 0]."""
    if isinstance(given, np.ndarray):
        return given.dtype.kind == "b"
    try:
        return any(isinstance(v, (bool, np.bool_)) or (isinstance(v, np.ndarray) and v.dtype.kind == "b")
                   for v in given)
    except TypeError:
        return False


def _shown(value) -> str:
    return bounded_repr(value, 60)
