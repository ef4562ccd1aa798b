"""Metrics for several targets (ours; issue 12): multi-target OSPA with its localisation and
cardinality parts, and track quality judged by the truth per target for labelled estimates.

Pure functions over arrays. The truth is ``(T, K, 3)``: target k's position at step t while it
is detectable (present and not occluded), NaN otherwise. The estimates are one
``(labels (m,), positions (m, 3))`` pair per step: the team's confirmed tracks.

Track quality, per step: each detectable target is **held** when a confirmed track is assigned
to it, else **missed**; each confirmed track assigned to no target is a **false track** (this
includes a track while every target is hidden, the single-target metrics' phantom). The
assignment is the largest set of (target, track) pairs within the gate (boundary included), and
among those the one of least total distance: :func:`gated_assignment`. With one target, held
steps are :func:`trackjam.metrics.track_quality.track_quality`'s, missed steps are its missed
and false-track steps, and false tracks are its false-track and phantom steps.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from trackjam.arguments import numeric, real

# Per-target, per-step class codes of :func:`target_classes`.
HELD, MISSED, UNDETECTABLE = range(3)
TARGET_CLASSES = ("held", "missed", "undetectable")

MAX_LENGTH = 1e5  # m, the configuration's bound on a length (config/limits.py; tests/test_config_hostile.py holds them equal)
# The arguments' bounds: the cutoff c and the gate are lengths of the configuration, (0,
# MAX_LENGTH]; the order p lies in [1, ORDER_MAX], ORDER_MAX the largest order at which
# MAX_LENGTH^p times 10^12 (more points than memory holds) stays a finite float, so that no sum
# of n c^p overflows (59; the configuration allows up to 10).
ORDER_MAX = math.floor(math.log(sys.float_info.max / 1e12) / math.log(MAX_LENGTH))


def _rows(name: str, value, undetectable: bool = False) -> np.ndarray:
    """``value`` as float rows (m, 3): finite, or with ``undetectable`` finite or all NaN. An
    empty list or array of one dimension is the empty set (0, 3)."""
    a = numeric(name, value)
    if a.ndim == 1 and a.size == 0:
        return a.reshape(0, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected rows of 3 entries (m, 3), one point each, got shape {a.shape}")
    _finite_rows(name, a, undetectable)
    return a


def _finite_rows(name: str, a: np.ndarray, undetectable: bool) -> None:
    finite = np.isfinite(a)
    if finite.all():
        return
    if not undetectable:
        raise ValueError(f"{name}: must be finite, got {'NaN' if np.isnan(a).any() else 'an infinite value'}")
    if np.isinf(a).any() or np.any(~finite.all(axis=-1) & ~np.isnan(a).all(axis=-1)):
        raise ValueError(f"{name}: each row must be a finite position or all NaN (undetectable), "
                         f"got {'an infinite value' if np.isinf(a).any() else 'a row partly NaN'}")


def _gate(gate) -> float:
    return real("gate", gate, 0.0, MAX_LENGTH, above=True)


def _ospa_bounds(c, p) -> tuple[float, float]:
    c = real("c", c, 0.0, MAX_LENGTH, above=True)
    p = real("p", p, 1.0, ORDER_MAX)
    if c**p < sys.float_info.min:  # c^p of a subnormal or 0: every distance and the cardinality part round to 0
        raise ValueError(f"c, p: c^p = {c:g}^{p:g} is below the smallest normal float, so the OSPA would round to 0; "
                         "use a larger cutoff c or a smaller order p")
    return c, p


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):  # points 1e308 apart are infinitely far: beyond any gate or cutoff
        return np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1)


def ospa_parts(truth, estimate, c: float = 10.0, p: float = 2.0) -> tuple[float, float, float]:
    """OSPA(p, c) between two finite point sets (m, 3) and (n, 3) [m], with its localisation and
    cardinality parts: ``(ospa, localisation, cardinality)``, ``ospa^p = loc^p + card^p``.

    For m <= n: loc^p = min over assignments of sum d_c(x_i, y_pi(i))^p / n,
    card^p = c^p (n - m) / n, d_c = min(d, c) (Schuhmacher, Vo and Vo 2008). Both empty: 0.

    Checked: ``truth`` and ``estimate`` finite rows of 3 (an empty list: the empty set), ``c``
    in (0, 1e5] m (``MAX_LENGTH``), ``p`` in [1, ``ORDER_MAX``] (59: no sum of c^p overflows), and
    c^p not below the smallest normal float.
    """
    c, p = _ospa_bounds(c, p)
    x, y = _rows("truth", truth), _rows("estimate", estimate)
    return _ospa_parts(x, y, c, p)


def _ospa_parts(x: np.ndarray, y: np.ndarray, c: float, p: float) -> tuple[float, float, float]:
    """:func:`ospa_parts` of checked point sets and bounds."""
    m, n = sorted((len(x), len(y)))
    if n == 0:
        return 0.0, 0.0, 0.0
    loc = 0.0
    if m:
        cost = np.minimum(_distances(x, y), c) ** p
        rows, cols = linear_sum_assignment(cost)
        loc = float(cost[rows, cols].sum())
    card = float(c) ** p * (n - m)
    return ((loc + card) / n) ** (1 / p), (loc / n) ** (1 / p), (card / n) ** (1 / p)


def _present(rows: np.ndarray) -> np.ndarray:
    return np.isfinite(rows).all(axis=-1)


def _estimates(estimates: Iterable, steps: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The estimates as a list of (labels, positions) pairs, one per step: any iterable of
    pairs (a list, a tuple, a generator) is taken once."""
    if isinstance(estimates, (str, bytes, np.ndarray)) or not isinstance(estimates, Iterable):
        raise TypeError(f"estimates: expected one (labels, positions) pair per step (a list or any iterable), "
                        f"got {type(estimates).__name__}")
    estimates = list(estimates)
    if len(estimates) != steps:
        raise ValueError(f"estimates: need one estimate per step ({steps}), got {len(estimates)}")
    out = []
    for t, pair in enumerate(estimates):
        items = None if isinstance(pair, (str, bytes)) or not isinstance(pair, Iterable) else tuple(pair)
        if items is None or len(items) != 2:
            got = type(pair).__name__ if items is None else f"{len(items)} items"
            raise TypeError(f"estimates[{t}]: expected a (labels, positions) pair, got {got}")
        pair = items
        labels, positions = np.asarray(pair[0]), _rows(f"estimates[{t}] positions", pair[1])
        if labels.ndim > 1:
            raise ValueError(f"estimates[{t}] labels: expected one label per position, got shape {labels.shape}")
        labels = labels.reshape(-1)
        if len(labels) != len(positions):
            raise ValueError(f"estimates[{t}]: {len(labels)} labels for {len(positions)} positions")
        out.append((labels, positions))
    return out


def _truth(truth) -> np.ndarray:
    truth = numeric("truth", truth)
    if truth.ndim != 3 or truth.shape[2] != 3:
        raise ValueError(f"truth: must be (T, K, 3), got shape {truth.shape}")
    _finite_rows("truth", truth, undetectable=True)
    return truth


def ospa_series(truth, estimates: Iterable, c: float = 10.0, p: float = 2.0) -> np.ndarray:
    """(T, 3) per step: OSPA, localisation and cardinality parts between the detectable targets
    and the estimates' positions [m]. ``truth`` (T, K, 3), each row finite or all NaN;
    ``estimates`` any iterable of T (labels, positions) pairs; ``c`` and ``p`` as
    :func:`ospa_parts`."""
    c, p = _ospa_bounds(c, p)
    truth = _truth(truth)
    est = _estimates(estimates, len(truth))
    return np.array([_ospa_parts(x[_present(x)], pos, c, p) for x, (_, pos) in zip(truth, est)]).reshape(-1, 3)


def gated_assignment(truth, positions, gate: float) -> np.ndarray:
    """For each target (rows of ``truth`` (K, 3), NaN: undetectable), the index of the track in
    ``positions`` (m, 3) assigned to it, or -1: the largest set of pairs within ``gate``
    (distance <= gate), of least total distance among those sets.

    Checked: ``truth`` rows finite or all NaN (an infinite coordinate is refused, not taken as
    undetectable), ``positions`` finite rows (an empty list: none), ``gate`` in (0, 1e5] m."""
    gate = _gate(gate)
    return _gated_assignment(_rows("truth", truth, undetectable=True), _rows("positions", positions), gate)


def _gated_assignment(truth: np.ndarray, positions: np.ndarray, gate: float) -> np.ndarray:
    """:func:`gated_assignment` of checked arguments."""
    out = np.full(len(truth), -1, dtype=np.int64)
    live = np.flatnonzero(_present(truth))
    if not len(live) or not len(positions):
        return out
    d = _distances(truth[live], positions)
    within = d <= gate
    # a pair outside the gate costs more than any set of pairs inside it, so the assignment first
    # takes as many gated pairs as there can be, then the least distance among them
    cost = np.where(within, d, gate * (min(d.shape) + 1))
    rows, cols = linear_sum_assignment(cost)
    keep = within[rows, cols]
    out[live[rows[keep]]] = cols[keep]
    return out


def target_classes(truth, estimates: Iterable, gate: float = 5.0) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Per step and target, what :func:`gated_assignment` makes of the estimates.

    Returns ``(classes (T, K) int8: HELD, MISSED, UNDETECTABLE; false_tracks (T,): confirmed
    tracks assigned to no target; holder: per step a (K,) object array of the label holding each
    target, None where none does)``. ``truth`` (T, K, 3), each row finite or all NaN;
    ``estimates`` any iterable (a generator too) of T (labels, positions) pairs; ``gate`` as
    :func:`gated_assignment`."""
    gate = _gate(gate)
    truth = _truth(truth)
    est = _estimates(estimates, len(truth))
    T, K = truth.shape[:2]
    classes = np.full((T, K), UNDETECTABLE, dtype=np.int8)
    false_tracks = np.zeros(T, dtype=np.int64)
    holder = []
    for t, (x, (labels, positions)) in enumerate(zip(truth, est)):
        assigned = _gated_assignment(x, positions, gate)
        classes[t, _present(x)] = MISSED
        classes[t, assigned >= 0] = HELD
        false_tracks[t] = len(positions) - int((assigned >= 0).sum())
        holder.append(np.array([labels[a] if a >= 0 else None for a in assigned], dtype=object))
    return classes, false_tracks, holder


def _switches(holders: list) -> int:
    """Times the label holding a target differs from the label that held it last."""
    held = [h for h in holders if h is not None]
    return int(sum(bool(a != b) for a, b in zip(held, held[1:])))


def multi_track_quality(truth, estimates: Iterable, gate: float = 5.0, ids: Sequence | None = None) -> dict:
    """The track quality of a run with several targets; every value is JSON-serialisable (plain
    ints, floats, None; numpy scalars among ``ids`` are given as Python's).

    ``truth`` (T, K, 3), each row a finite position or all NaN (undetectable); ``estimates`` any
    iterable (a list, a generator) of T (labels, positions) pairs, read once; ``gate`` in (0,
    1e5] m; ``ids`` one per target.

    Keys:
    - ``gate_m``: the gate [m]; ``ids``: the targets' ids (their indices when not given);
    - per target, lists in the order of ``ids``: ``detectable_steps``, ``held_steps``,
      ``missed_steps`` (they sum to ``detectable_steps``), ``held_share`` (None for a target
      never detectable), ``label_switches`` (times the label holding it changed);
    - ``held_steps_total``, ``detectable_steps_total``, ``held_share_total`` (held over
      detectable target-steps; None when there are none);
    - ``false_track_steps``: steps with at least one false track; ``false_tracks``: their count
      summed over steps.
    """
    gate = _gate(gate)
    if ids is not None and (isinstance(ids, (str, bytes)) or not isinstance(ids, Iterable)):
        raise TypeError(f"ids: expected one id per target (a list), got {type(ids).__name__}")
    classes, false_tracks, holder = target_classes(truth, estimates, gate)
    K = classes.shape[1]
    ids = list(range(K)) if ids is None else [v.item() if isinstance(v, np.generic) else v for v in ids]
    if len(ids) != K:
        raise ValueError(f"ids: {len(ids)} ids for {K} targets")
    detectable = (classes != UNDETECTABLE).sum(axis=0)
    held = (classes == HELD).sum(axis=0)
    n_det, n_held = int(detectable.sum()), int(held.sum())
    return {
        "gate_m": float(gate),
        "ids": ids,
        "detectable_steps": [int(v) for v in detectable],
        "held_steps": [int(v) for v in held],
        "missed_steps": [int(v) for v in detectable - held],
        "held_share": [float(h / d) if d else None for h, d in zip(held, detectable)],
        "label_switches": [_switches([h[k] for h in holder]) for k in range(K)],
        "held_steps_total": n_held,
        "detectable_steps_total": n_det,
        "held_share_total": n_held / n_det if n_det else None,
        "false_track_steps": int((false_tracks > 0).sum()),
        "false_tracks": int(false_tracks.sum()),
    }
