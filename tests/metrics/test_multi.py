"""Multi-target OSPA and per-target track quality: brute force over assignments on small sets,
hand cases, and the single-target metrics for one target."""

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.metrics.multi import (
    HELD,
    MISSED,
    UNDETECTABLE,
    gated_assignment,
    multi_track_quality,
    ospa_parts,
    ospa_series,
    target_classes,
)
from trackjam.metrics.ospa import ospa
from trackjam.metrics.track_quality import step_classes, track_quality

coord = st.floats(-20, 20, allow_nan=False)
point_sets = st.lists(st.tuples(coord, coord, coord), min_size=0, max_size=4).map(lambda v: np.array(v, float).reshape(-1, 3))


def _brute_ospa(x, y, c, p):
    if len(x) > len(y):
        x, y = y, x
    m, n = len(x), len(y)
    if n == 0:
        return 0.0, 0.0, 0.0
    d = np.minimum(np.linalg.norm(x[:, None] - y[None], axis=-1), c) ** p if m else np.zeros((0, n))
    loc = min(sum(d[i, j] for i, j in enumerate(perm)) for perm in itertools.permutations(range(n), m))
    card = c**p * (n - m)
    return ((loc + card) / n) ** (1 / p), (loc / n) ** (1 / p), (card / n) ** (1 / p)


@settings(max_examples=300, deadline=None)
@given(x=point_sets, y=point_sets, c=st.sampled_from([1.0, 5.0, 10.0]), p=st.sampled_from([1.0, 2.0, 3.0]))
def test_ospa_equals_brute_force_over_assignments(x, y, c, p):
    got = ospa_parts(x, y, c, p)
    assert got == pytest.approx(_brute_ospa(x, y, c, p), rel=1e-9, abs=1e-9)
    assert got == pytest.approx(ospa_parts(y, x, c, p), rel=1e-12, abs=1e-12)
    total, loc, card = got
    assert total**p == pytest.approx(loc**p + card**p, rel=1e-9, abs=1e-9) and 0 <= total <= c + 1e-12


@settings(max_examples=200, deadline=None)
@given(
    x=st.one_of(st.none(), st.tuples(coord, coord, coord)),
    y=st.one_of(st.none(), st.tuples(coord, coord, coord)),
    c=st.sampled_from([2.0, 10.0]),
    p=st.sampled_from([1.0, 2.0]),
)
def test_sets_of_at_most_one_give_the_single_target_ospa(x, y, c, p):
    want = ospa(None if x is None else np.array(x), None if y is None else np.array(y), c, p)
    as_set = [np.array(v, float).reshape(-1, 3) if v is not None else np.zeros((0, 3)) for v in (x, y)]
    assert ospa_parts(*as_set, c, p)[0] == pytest.approx(want, rel=1e-12, abs=1e-12)


def test_ospa_hand_cases():
    a = np.array([[0.0, 0, 0], [10.0, 0, 0]])
    assert ospa_parts(a, a) == (0.0, 0.0, 0.0)
    # one of two targets found exactly: only the cardinality part, c / sqrt(2)
    assert ospa_parts(a, a[:1]) == pytest.approx((10 / math.sqrt(2), 0.0, 10 / math.sqrt(2)))
    # both found 3 m off: the localisation part alone, 3 m; crossed labels do not matter
    assert ospa_parts(a, a[::-1] + [0, 3, 0]) == pytest.approx((3.0, 3.0, 0.0))
    assert ospa_parts(np.zeros((0, 3)), a, c=4.0) == pytest.approx((4.0, 0.0, 4.0))
    with pytest.raises(ValueError):
        ospa_parts([[np.nan, 0, 0]], a)


def test_ospa_series_takes_nan_rows_as_undetectable():
    truth = np.array([[[0.0, 0, 0], [np.nan] * 3], [[np.nan] * 3] * 2])
    est = [([7], [[0.0, 4, 0]]), ([], np.zeros((0, 3)))]
    series = ospa_series(truth, est)
    assert series.shape == (2, 3)
    assert series[0] == pytest.approx((4.0, 4.0, 0.0)) and np.array_equal(series[1], [0, 0, 0])


def _brute_assignment(truth, positions, gate):
    """(pairs, total distance) of the best partial matching within the gate."""
    live = [k for k in range(len(truth)) if np.isfinite(truth[k]).all()]
    best = (0, 0.0)
    for r in range(min(len(live), len(positions)) + 1):
        for ks in itertools.combinations(live, r):
            for js in itertools.permutations(range(len(positions)), r):
                d = [np.linalg.norm(truth[k] - positions[j]) for k, j in zip(ks, js)]
                if all(v <= gate for v in d) and (r > best[0] or (r == best[0] and sum(d) < best[1] - 1e-12)):
                    best = (r, sum(d))
    return best


@settings(max_examples=300, deadline=None)
@given(
    truth=st.lists(st.one_of(st.none(), st.tuples(coord, coord, coord)), min_size=0, max_size=4),
    positions=point_sets,
    gate=st.sampled_from([2.0, 5.0, 15.0]),
)
def test_the_gated_assignment_is_the_best_partial_matching(truth, positions, gate):
    truth = np.array([[np.nan] * 3 if v is None else v for v in truth], float).reshape(-1, 3)
    a = gated_assignment(truth, positions, gate)
    used = a[a >= 0]
    assert len(set(used)) == len(used)  # one track per target at most
    assert np.all(np.isfinite(truth[a >= 0]).all(axis=1))
    d = [np.linalg.norm(truth[k] - positions[j]) for k, j in enumerate(a) if j >= 0]
    assert all(v <= gate for v in d)
    pairs, total = _brute_assignment(truth, positions, gate)
    assert len(d) == pairs and sum(d) == pytest.approx(total, abs=1e-9)


def test_the_assignment_takes_more_pairs_before_nearer_ones():
    # the track at 1 m from target 0 could take it, but then target 1 (4 m from it) has none
    truth = np.array([[0.0, 0, 0], [5.0, 0, 0]])
    positions = np.array([[1.0, 0, 0], [-4.0, 0, 0]])
    assert list(gated_assignment(truth, positions, 5.0)) == [1, 0]
    assert list(gated_assignment(truth, positions[:1], 5.0)) == [0, -1]  # the nearer target gets it
    assert list(gated_assignment(truth, [[5.0, 0, 5.0]], 5.0)) == [-1, 0]  # boundary included


def test_target_classes_on_a_hand_case():
    nan = [np.nan] * 3
    truth = np.array([
        [[0.0, 0, 0], [50.0, 0, 0]],
        [[1.0, 0, 0], [51.0, 0, 0]],
        [[2.0, 0, 0], nan],
        [nan, nan],
    ])
    est = [
        (["A", "B"], [[0.5, 0, 0], [50.0, 3, 0]]),  # both held
        (["A"], [[30.0, 0, 0]]),  # both missed, one false track
        (["B", "C"], [[2.0, 1, 0], [51.0, 0, 0]]),  # target 0 held by B; C near the occluded one: false
        (["C"], [[0.0, 0, 0]]),  # nobody detectable: a false track (the phantom)
    ]
    classes, false_tracks, holder = target_classes(truth, est, gate=5.0)
    assert classes.tolist() == [[HELD, HELD], [MISSED, MISSED], [HELD, UNDETECTABLE], [UNDETECTABLE] * 2]
    assert false_tracks.tolist() == [0, 1, 1, 1]
    assert [list(h) for h in holder] == [["A", "B"], [None, None], ["B", None], [None, None]]
    q = multi_track_quality(truth, est, gate=5.0, ids=["x", "y"])
    assert q["ids"] == ["x", "y"] and q["detectable_steps"] == [3, 2] and q["held_steps"] == [2, 1]
    assert q["missed_steps"] == [1, 1] and q["held_share"] == pytest.approx([2 / 3, 0.5])
    assert q["label_switches"] == [1, 0]  # target 0: A, then B
    assert q["held_steps_total"] == 3 and q["detectable_steps_total"] == 5 and q["held_share_total"] == 0.6
    assert q["false_track_steps"] == 3 and q["false_tracks"] == 3


def test_a_target_never_detectable_has_no_share():
    truth = np.full((2, 1, 3), np.nan)
    q = multi_track_quality(truth, [([], np.zeros((0, 3)))] * 2)
    assert q["held_share"] == [None] and q["held_share_total"] is None and q["label_switches"] == [0]


@settings(max_examples=200, deadline=None)
@given(
    rows=st.lists(
        st.tuples(
            st.booleans(),  # detectable
            st.one_of(st.none(), st.floats(0, 12)),  # the confirmed estimate's distance from the truth
        ),
        min_size=1,
        max_size=25,
    ),
    gate=st.sampled_from([2.0, 5.0]),
)
def test_one_target_agrees_with_the_single_target_track_quality(rows, gate):
    T = len(rows)
    truth_pos = np.column_stack([np.arange(T, dtype=float), np.zeros(T), np.full(T, 20.0)])
    detectable = np.array([d for d, _ in rows])
    est_pos = np.array([[np.nan] * 3 if e is None else truth_pos[t] + [0, e, 0] for t, (_, e) in enumerate(rows)])
    confirmed = np.array([e is not None for _, e in rows])
    steps = {
        "target_detectable": detectable,
        "existence": np.where(confirmed, 0.9, 0.1),
        **{f"truth_{a}": truth_pos[:, i] for i, a in enumerate("xyz")},
        **{f"est_{a}": est_pos[:, i] for i, a in enumerate("xyz")},
    }
    one = track_quality(steps, gate)
    codes = step_classes(steps, gate)
    truth = np.where(detectable[:, None], truth_pos, np.nan)[:, None, :]
    est = [(["T1"], est_pos[t : t + 1]) if confirmed[t] else ([], np.zeros((0, 3))) for t in range(T)]
    multi = multi_track_quality(truth, est, gate)
    classes, false_tracks, _ = target_classes(truth, est, gate)
    assert multi["held_steps"] == [one["held_steps"]] and multi["detectable_steps"] == [one["detectable_steps"]]
    assert multi["missed_steps"] == [one["missed_steps"] + one["false_track_steps"]]
    assert multi["false_tracks"] == one["false_track_steps"] + one["phantom_steps"] == multi["false_track_steps"]
    assert multi["held_share"] == [one["held_share"]]
    assert np.array_equal(classes[:, 0] == HELD, codes == 0) and multi["label_switches"] == [0]


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match="one estimate per step"):
        multi_track_quality(np.zeros((2, 1, 3)), [([], np.zeros((0, 3)))])
    with pytest.raises(ValueError, match=r"\(T, K, 3\)"):
        ospa_series(np.zeros((2, 3)), [([], np.zeros((0, 3)))] * 2)
    with pytest.raises(ValueError, match="labels"):
        target_classes(np.zeros((1, 1, 3)), [([1, 2], np.zeros((1, 3)))])
    with pytest.raises(ValueError, match="gate"):
        gated_assignment(np.zeros((1, 3)), np.zeros((1, 3)), 0.0)
    with pytest.raises(ValueError, match="ids"):
        multi_track_quality(np.zeros((1, 2, 3)), [([], np.zeros((0, 3)))], ids=[1])


def test_two_tracks_on_one_target_and_one_track_between_two():
    """Two tracks on one target: the nearer holds it, the other is a false track. One track
    between two targets, within the gate of both: it holds the nearer, the other is missed,
    and nothing is false. A target not yet present (NaN) is neither held nor missed, and a
    track near where it will appear is false."""
    nan = [np.nan] * 3
    truth = np.array([
        [[0.0, 0, 0], [40.0, 0, 0]],
        [[0.0, 0, 0], [6.0, 0, 0]],
        [[0.0, 0, 0], nan],
    ])
    est = [
        (["A", "B"], [[1.0, 0, 0], [0.0, 2, 0]]),
        (["A"], [[2.5, 0, 0]]),
        (["A", "B"], [[0.5, 0, 0], [40.0, 0, 0]]),
    ]
    classes, false_tracks, holder = target_classes(truth, est, gate=5.0)
    assert classes.tolist() == [[HELD, MISSED], [HELD, MISSED], [HELD, UNDETECTABLE]]
    assert false_tracks.tolist() == [1, 0, 1]
    assert [list(h) for h in holder] == [["A", None], ["A", None], ["A", None]]
    q = multi_track_quality(truth, est, gate=5.0)
    assert q["detectable_steps"] == [3, 2] and q["held_steps"] == [3, 0] and q["missed_steps"] == [0, 2]
    assert q["false_track_steps"] == 2 and q["false_tracks"] == 2
    ospa = ospa_series(truth, est)
    # step 3: one target, two tracks: loc^2 = 0.5^2 / 2, card^2 = 10^2 / 2
    assert ospa[2] == pytest.approx([math.sqrt((0.25 + 100) / 2), math.sqrt(0.125), math.sqrt(50)])
