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

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

# Per-target, per-step class codes of :func:`target_classes`.
HELD, MISSED, UNDETECTABLE = range(3)
TARGET_CLASSES = ("held", "missed", "undetectable")


def _points(x) -> np.ndarray:
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    if not np.isfinite(x).all():
        raise ValueError("a point set holds NaN or infinite coordinates")
    return x


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1)


def ospa_parts(truth, estimate, c: float = 10.0, p: float = 2.0) -> tuple[float, float, float]:
    """OSPA(p, c) between two finite point sets (m, 3) and (n, 3) [m], with its localisation and
    cardinality parts: ``(ospa, localisation, cardinality)``, ``ospa^p = loc^p + card^p``.

    For m <= n: loc^p = min over assignments of sum d_c(x_i, y_pi(i))^p / n,
    card^p = c^p (n - m) / n, d_c = min(d, c) (Schuhmacher, Vo and Vo 2008). Both empty: 0.
    """
    if c <= 0 or p <= 0:
        raise ValueError("OSPA needs c > 0 and p > 0")
    x, y = _points(truth), _points(estimate)
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


def _estimates(estimates: Sequence, steps: int) -> list[tuple[np.ndarray, np.ndarray]]:
    if len(estimates) != steps:
        raise ValueError(f"need one estimate per step ({steps}), got {len(estimates)}")
    out = []
    for labels, positions in estimates:
        labels, positions = np.asarray(labels).reshape(-1), _points(positions)
        if len(labels) != len(positions):
            raise ValueError(f"{len(labels)} labels for {len(positions)} positions")
        out.append((labels, positions))
    return out


def _truth(truth) -> np.ndarray:
    truth = np.asarray(truth, dtype=float)
    if truth.ndim != 3 or truth.shape[2] != 3:
        raise ValueError(f"the truth must be (T, K, 3), got shape {truth.shape}")
    return truth


def ospa_series(truth, estimates: Sequence, c: float = 10.0, p: float = 2.0) -> np.ndarray:
    """(T, 3) per step: OSPA, localisation and cardinality parts between the detectable targets
    and the estimates' positions [m]."""
    truth = _truth(truth)
    est = _estimates(estimates, len(truth))
    return np.array([ospa_parts(x[_present(x)], pos, c, p) for x, (_, pos) in zip(truth, est)]).reshape(-1, 3)


def gated_assignment(truth, positions, gate: float) -> np.ndarray:
    """For each target (rows of ``truth`` (K, 3), NaN: undetectable), the index of the track in
    ``positions`` (m, 3) assigned to it, or -1: the largest set of pairs within ``gate``
    (distance <= gate), of least total distance among those sets."""
    if not gate > 0:
        raise ValueError(f"the gate must be > 0 m, got {gate}")
    truth, positions = np.asarray(truth, dtype=float).reshape(-1, 3), _points(positions)
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


def target_classes(truth, estimates: Sequence, gate: float = 5.0) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Per step and target, what :func:`gated_assignment` makes of the estimates.

    Returns ``(classes (T, K) int8: HELD, MISSED, UNDETECTABLE; false_tracks (T,): confirmed
    tracks assigned to no target; holder: per step a (K,) object array of the label holding each
    target, None where none does)``."""
    truth = _truth(truth)
    est = _estimates(estimates, len(truth))
    T, K = truth.shape[:2]
    classes = np.full((T, K), UNDETECTABLE, dtype=np.int8)
    false_tracks = np.zeros(T, dtype=np.int64)
    holder = []
    for t, (x, (labels, positions)) in enumerate(zip(truth, est)):
        assigned = gated_assignment(x, positions, gate)
        classes[t, _present(x)] = MISSED
        classes[t, assigned >= 0] = HELD
        false_tracks[t] = len(positions) - int((assigned >= 0).sum())
        holder.append(np.array([labels[a] if a >= 0 else None for a in assigned], dtype=object))
    return classes, false_tracks, holder


def _switches(holders: list) -> int:
    """Times the label holding a target differs from the label that held it last."""
    held = [h for h in holders if h is not None]
    return sum(a != b for a, b in zip(held, held[1:]))


def multi_track_quality(truth, estimates: Sequence, gate: float = 5.0, ids: Sequence | None = None) -> dict:
    """The track quality of a run with several targets; every value is JSON-serialisable.

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
    classes, false_tracks, holder = target_classes(truth, estimates, gate)
    K = classes.shape[1]
    ids = list(range(K)) if ids is None else list(ids)
    if len(ids) != K:
        raise ValueError(f"{len(ids)} ids for {K} targets")
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
