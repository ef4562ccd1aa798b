"""Track quality judged by the truth: held, false track, missed, phantom, and the times to
acquire and re-acquire the target."""

import json
import subprocess
import sys

import numpy as np
import pytest

from trackjam.metrics.track_quality import (
    CLASSES,
    CONFIRM,
    FALSE_TRACK,
    HELD,
    MISSED,
    PHANTOM,
    SILENT,
    step_classes,
    track_quality,
)


def log(detectable, offsets, existence, present=None):
    """A steps log: the truth at (10 t, 0, 0); the estimate at truth + offset (None: no
    estimate). ``present`` (default: every step) marks steps the truth exists."""
    T = len(detectable)
    present = np.ones(T, bool) if present is None else np.asarray(present, bool)
    truth = np.stack([10.0 * np.arange(T), np.zeros(T), np.zeros(T)], axis=1)
    truth[~present] = np.nan
    est = np.full((T, 3), np.nan)
    for k, off in enumerate(offsets):
        if off is not None:
            base = truth[k] if present[k] else np.zeros(3)
            est[k] = base + np.asarray(off, float)
    cols = {"t": np.arange(1, T + 1), "target_detectable": np.asarray(detectable, bool),
            "target_exists": present, "existence": np.asarray(existence, float)}
    for i, a in enumerate("xyz"):
        cols[f"truth_{a}"] = truth[:, i]
        cols[f"est_{a}"] = est[:, i]
    return cols


def reference(steps, gate):
    """The definitions step by step, in plain Python."""
    T = len(steps["t"])
    classes = []
    for k in range(T):
        x = np.array([steps[f"truth_{a}"][k] for a in "xyz"])
        e = np.array([steps[f"est_{a}"][k] for a in "xyz"])
        confirmed = steps["existence"][k] > 0.5 and not np.isnan(e).any()
        if steps["target_detectable"][k]:
            if not confirmed:
                classes.append("missed")
            elif np.sqrt(((e - x) ** 2).sum()) <= gate:
                classes.append("held")
            else:
                classes.append("false_track")
        else:
            classes.append("phantom" if confirmed else "silent")
    det = [bool(v) for v in steps["target_detectable"]]
    first_det = det.index(True) if True in det else None
    first = None
    if first_det is not None:
        for k in range(first_det, T):
            if classes[k] == "held":
                first = k - first_det
                break
    reacq = []
    k = first_det + 1 if first_det is not None else T
    while k < T:
        if not det[k - 1] and det[k]:
            hit = None
            j = k
            while j < T and det[j]:
                if classes[j] == "held":
                    hit = j - k
                    break
                j += 1
            reacq.append(hit)
        k += 1
    return classes, first, reacq


# steps:        0      1      2      3      4     5     6      7      8      9
DET = [True, True, True, True, False, False, True, True, True, True]
OFFS = [None, (1, 0, 0), (0, 9, 0), (3, 4, 0), (0, 0, 0), None, None, (6, 0, 0), (0, 2, 0), None]
EXIST = [0.3, 0.9, 0.9, 0.9, 0.8, 0.1, 0.2, 0.9, 0.9, 0.4]


def test_a_hand_built_run_has_the_classes_and_times_worked_out_by_hand():
    steps = log(DET, OFFS, EXIST)
    names = [CLASSES[c] for c in step_classes(steps, gate=5.0)]
    assert names == ["missed", "held", "false_track", "held", "phantom", "silent",
                     "missed", "false_track", "held", "missed"]
    q = track_quality(steps, gate=5.0)
    assert q == {
        "gate_m": 5.0,
        "detectable_steps": 8,
        "held_steps": 3,
        "false_track_steps": 2,
        "missed_steps": 3,
        "held_share": 3 / 8,
        "false_track_share": 2 / 8,
        "missed_share": 3 / 8,
        "phantom_steps": 1,
        "first_acquisition_steps": 1,
        "reacquisition_steps": [2],  # the spell ends at step 5; held first at step 8
        "reacquired_after_last_spell": True,
    }


def test_the_gate_is_inclusive_and_sets_the_line_between_held_and_false_track():
    # offset (3, 4, 0) is exactly 5 m from the truth
    steps = log([True], [(3, 4, 0)], [0.9])
    assert step_classes(steps, gate=5.0)[0] == HELD
    assert step_classes(steps, gate=np.nextafter(5.0, 0))[0] == FALSE_TRACK
    assert track_quality(steps, gate=4.0)["false_track_share"] == 1.0


def test_confirmed_means_existence_strictly_above_one_half_with_a_position():
    assert CONFIRM == 0.5
    off = (0, 0, 0)
    steps = log([True] * 4, [off, off, None, off], [0.5, np.nextafter(0.5, 1), 0.99, np.nan])
    assert list(step_classes(steps)) == [MISSED, HELD, MISSED, MISSED]


def test_a_run_whose_target_is_never_detectable_has_no_shares_and_counts_its_phantoms():
    steps = log([False] * 4, [None, (0, 0, 0), (1, 1, 1), None], [0.1, 0.9, 0.7, 0.6],
                present=[False, False, True, True])
    assert list(step_classes(steps)) == [SILENT, PHANTOM, PHANTOM, SILENT]
    q = track_quality(steps)
    assert q["detectable_steps"] == 0 and q["phantom_steps"] == 2
    assert q["held_share"] is q["false_track_share"] is q["missed_share"] is None
    assert q["first_acquisition_steps"] is None
    assert q["reacquisition_steps"] == [] and q["reacquired_after_last_spell"] is None


def test_a_team_that_never_confirms_misses_every_detectable_step_and_never_reacquires():
    det = [True, True, False, True, True, False, True]
    q = track_quality(log(det, [None] * 7, [0.2] * 7))
    assert q["missed_share"] == 1.0 and q["held_share"] == 0.0
    assert q["first_acquisition_steps"] is None
    assert q["reacquisition_steps"] == [None, None]
    assert q["reacquired_after_last_spell"] is False


def test_a_spell_at_the_start_delays_the_first_acquisition_and_is_no_reacquisition():
    det = [False, False, True, True, True]
    steps = log(det, [None, None, None, (1, 0, 0), (1, 0, 0)], [0.0, 0.0, 0.3, 0.9, 0.9],
                present=[False, True, True, True, True])
    q = track_quality(steps)
    assert q["first_acquisition_steps"] == 1  # detectable from step 2, held from step 3
    assert q["reacquisition_steps"] == [] and q["reacquired_after_last_spell"] is None


def test_a_spell_at_the_end_is_not_waited_for():
    det = [True, True, False, False]
    q = track_quality(log(det, [(0, 0, 0)] * 4, [0.9] * 4, present=[True, True, True, False]))
    assert q["first_acquisition_steps"] == 0 and q["phantom_steps"] == 2
    assert q["reacquisition_steps"] == [] and q["reacquired_after_last_spell"] is None


def test_reacquisition_is_looked_for_only_until_the_next_spell():
    # spells at 2 and 5; held only after the second one, two steps after it ends
    det = [True, True, False, True, True, False, True, True, True]
    offs = [(0, 0, 0), (0, 0, 0), None, None, None, None, None, None, (0, 0, 0)]
    ex = [0.9, 0.9, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.9]
    q = track_quality(log(det, offs, ex))
    assert q["reacquisition_steps"] == [None, 2]
    assert q["reacquired_after_last_spell"] is True
    assert q["first_acquisition_steps"] == 0


def test_held_at_once_after_a_spell_is_a_reacquisition_time_of_zero():
    det = [True, False, True]
    q = track_quality(log(det, [(0, 0, 0)] * 3, [0.9] * 3))
    assert q["reacquisition_steps"] == [0] and q["phantom_steps"] == 1


@pytest.mark.parametrize("seed", range(40))
def test_the_vectorised_metrics_match_the_definitions_step_by_step(seed):
    rng = np.random.default_rng(seed)
    T = int(rng.integers(1, 25))
    det = rng.random(T) < rng.uniform(0.2, 0.9)
    present = det | (rng.random(T) < 0.5)
    offs = [None if rng.random() < 0.3 else rng.normal(0, 5, 3) for _ in range(T)]
    steps = log(det, offs, rng.random(T), present=present)
    gate = float(rng.uniform(1, 8))
    classes, first, reacq = reference(steps, gate)
    assert [CLASSES[c] for c in step_classes(steps, gate)] == classes
    q = track_quality(steps, gate)
    assert q["first_acquisition_steps"] == first
    assert q["reacquisition_steps"] == reacq
    for name in ("held", "false_track", "missed", "phantom"):
        assert q[f"{name}_steps"] == classes.count(name)
    assert q["held_steps"] + q["false_track_steps"] + q["missed_steps"] == q["detectable_steps"] == det.sum()
    json.dumps(q, allow_nan=False)


def test_an_empty_log_has_nothing_to_report():
    q = track_quality(log([], [], []))
    assert q["detectable_steps"] == 0 and q["held_share"] is None and q["reacquisition_steps"] == []


def test_a_gate_that_is_not_positive_is_refused():
    with pytest.raises(ValueError, match="gate"):
        track_quality(log([True], [(0, 0, 0)], [0.9]), gate=0.0)


def test_a_detectable_step_without_a_true_position_is_refused():
    with pytest.raises(ValueError, match="true position"):
        step_classes(log([True], [(0, 0, 0)], [0.9], present=[False]))


@pytest.mark.parametrize("value", ["0", "-1", ".nan"])
def test_the_cli_refuses_a_gate_that_is_not_positive_in_one_line(value):
    r = subprocess.run(
        [sys.executable, "-m", "trackjam", "validate", "paper-fig3", "--set", f"metrics.gate={value}"],
        capture_output=True, text=True,
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and "metrics.gate" in lines[0]


@pytest.mark.parametrize("change, words", [
    (lambda c: c.update(target_detectable=c["target_detectable"][:, None]), "one-dimensional and of one length"),
    (lambda c: c.update(existence=c["existence"][:1]), "existence (1,) beside target_detectable (5,)"),
    (lambda c: c.update(target_detectable=np.array(["False"] * 5)), "target_detectable must hold booleans"),
    (lambda c: c.update(target_detectable=np.full(5, 0.4)), "target_detectable must hold booleans"),
    (lambda c: c.pop("est_z"), "missing the column(s) est_z"),
])
def test_columns_that_are_no_steps_log_are_refused(change, words):
    # a (5, 1) column was broadcast into 25 held steps of 5 (a share of 5.0); "False" counted as detectable
    cols = log([True] * 5, [(1, 0, 0)] * 5, [0.9] * 5)
    change(cols)
    for f in (track_quality, step_classes):
        with pytest.raises(ValueError, match=r"^steps: ") as err:
            f(cols)
        assert words in str(err.value)
