"""Track quality judged by the truth (ours, beyond the paper's OSPA).

At each step where the target is detectable the team's report is *held* (confirmed and within
the gate of the true position), a *false track* (confirmed but further off) or *missed* (not
confirmed). OSPA alone cannot tell a held track from one that has slipped off the target while
staying confirmed, since both can sit below the cut-off; these classes can. A step where the
target is absent or occluded is not classed, but a confirmed report there is a *phantom*.

Everything here works on the columns of a run's ``steps`` log (see the README, "What a run
writes"): ``target_detectable``, ``truth_x/y/z``, ``existence`` and ``est_x/y/z``, one row per
step in order.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from trackjam.estimation.fusion import CONFIRM

# Per-step class codes; CLASSES[code] is the class's name.
HELD, FALSE_TRACK, MISSED, PHANTOM, SILENT = range(5)
CLASSES = ("held", "false_track", "missed", "phantom", "silent")


def _xyz(steps: Mapping[str, np.ndarray], prefix: str) -> np.ndarray:
    return np.stack([np.asarray(steps[f"{prefix}_{a}"], dtype=float) for a in "xyz"], axis=-1)


COLUMNS = ("target_detectable", "existence", *(f"{p}_{a}" for p in ("truth", "est") for a in "xyz"))


def _columns(steps: Mapping[str, np.ndarray]) -> int:
    """The number of steps, once every column this module reads is there, one-dimensional and of
    one length, and ``target_detectable`` holds booleans: a (5, 1) column was broadcast into 25
    "held" steps of 5, and the text "False" counted as detectable."""
    missing = [c for c in COLUMNS if c not in steps]
    if missing:
        raise ValueError(f"steps: missing the column(s) {', '.join(missing)} (a run's steps log has them)")
    shapes = {c: np.shape(steps[c]) for c in COLUMNS}
    if any(len(sh) != 1 for sh in shapes.values()) or len(set(shapes.values())) != 1:
        raise ValueError(f"steps: the columns must be one-dimensional and of one length, got shapes "
                         f"{', '.join(f'{c} {sh}' for c, sh in shapes.items() if sh != shapes['target_detectable'])} "
                         f"beside target_detectable {shapes['target_detectable']}")
    if np.asarray(steps["target_detectable"]).dtype.kind != "b":
        raise ValueError(f"steps: target_detectable must hold booleans, got dtype "
                         f"{np.asarray(steps['target_detectable']).dtype}")
    return shapes["target_detectable"][0]


def _parts(steps: Mapping[str, np.ndarray], gate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(detectable, confirmed, within gate) per step."""
    if isinstance(gate, (bool, np.bool_)) or not gate > 0:
        raise ValueError(f"the gate must be > 0 m, got {gate}")
    _columns(steps)
    detectable = np.asarray(steps["target_detectable"], dtype=bool)
    truth, est = _xyz(steps, "truth"), _xyz(steps, "est")
    if np.any(detectable & ~np.isfinite(truth).all(axis=1)):
        raise ValueError("a detectable step has no true position")
    # NaN existence or a missing position is not a confirmed report
    confirmed = (np.asarray(steps["existence"], dtype=float) > CONFIRM) & np.isfinite(est).all(axis=1)
    with np.errstate(invalid="ignore"):
        within = np.linalg.norm(est - truth, axis=1) <= gate
    return detectable, confirmed, within


def step_classes(steps: Mapping[str, np.ndarray], gate: float = 5.0) -> np.ndarray:
    """The class of every step as an int8 code (HELD, FALSE_TRACK, MISSED at detectable steps;
    PHANTOM, a confirmed report while the target is absent or occluded; SILENT, no report then).
    ``np.asarray(CLASSES)[codes]`` gives the names."""
    detectable, confirmed, within = _parts(steps, gate)
    return np.select(
        [detectable & confirmed & within, detectable & confirmed, detectable, confirmed],
        [HELD, FALSE_TRACK, MISSED, PHANTOM],
        SILENT,
    ).astype(np.int8)


def _share(count: int, total: int) -> float | None:
    return count / total if total else None


def _spells(detectable: np.ndarray) -> list[tuple[int, int]]:
    """Undetectable spells that re-acquisition is measured after: maximal runs of
    undetectable steps that follow the first detectable step and are followed by a detectable
    one, as (first detectable step after the spell, first step of the next spell or the end)."""
    d = detectable.astype(np.int8)
    edges = np.diff(d)
    rises = np.flatnonzero(edges == 1) + 1  # first detectable step after a spell
    falls = np.flatnonzero(edges == -1) + 1  # first step of a spell
    stretch_ends = np.append(falls, len(d))
    # a spell before the target is first detectable belongs to the first acquisition
    if len(d) and not d[0]:
        rises = rises[1:]
    return [(int(r), int(stretch_ends[np.searchsorted(falls, r)])) for r in rises]


def track_quality(steps: Mapping[str, np.ndarray], gate: float = 5.0) -> dict:
    """The run's track quality; every value is JSON-serialisable (None where undefined).

    Keys (steps are rows of the log, one per dT = 1 s):
    - ``gate_m``: the gate [m];
    - ``detectable_steps``: steps at which the target is present and not occluded;
    - ``held_steps``, ``false_track_steps``, ``missed_steps``: their classes (they sum to
      ``detectable_steps``); ``held_share``, ``false_track_share``, ``missed_share``: the same as
      shares of the detectable steps (None when there are none);
    - ``phantom_steps``: confirmed reports while the target is absent or occluded;
    - ``first_acquisition_steps``: steps from the first detectable step to the first held one
      (0: held at once; None: never held or never detectable);
    - ``reacquisition_steps``: for every undetectable spell (occlusion or absence) after the
      target was first detectable and followed by detectable steps, in order: steps from the
      first detectable step after the spell to the first held step before the next spell
      (0: held at once; None: not re-acquired);
    - ``reacquired_after_last_spell``: whether the last of those spells was re-acquired (None
      when there is no such spell).
    """
    detectable, confirmed, within = _parts(steps, gate)
    held = detectable & confirmed & within
    n_det = int(detectable.sum())
    n_held = int(held.sum())
    n_false = int((detectable & confirmed & ~within).sum())
    n_missed = int((detectable & ~confirmed).sum())

    held_at = np.flatnonzero(held)
    first = None
    if n_held:
        first = int(held_at[0] - np.flatnonzero(detectable)[0])

    reacq: list[int | None] = []
    for start, stop in _spells(detectable):
        hits = held_at[(held_at >= start) & (held_at < stop)]
        reacq.append(int(hits[0] - start) if len(hits) else None)

    return {
        "gate_m": float(gate),
        "detectable_steps": n_det,
        "held_steps": n_held,
        "false_track_steps": n_false,
        "missed_steps": n_missed,
        "held_share": _share(n_held, n_det),
        "false_track_share": _share(n_false, n_det),
        "missed_share": _share(n_missed, n_det),
        "phantom_steps": int((~detectable & confirmed).sum()),
        "first_acquisition_steps": first,
        "reacquisition_steps": reacq,
        "reacquired_after_last_spell": (reacq[-1] is not None) if reacq else None,
    }
