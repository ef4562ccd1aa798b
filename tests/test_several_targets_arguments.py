"""The several-targets building blocks refuse bad arguments with one ValueError or TypeError
naming the argument (a fuzz hunt: a NaN cutoff reached scipy, an inf truth row was taken as
undetectable, a wrong-length ``exists`` broadcast, a NaN existence was fused, ``accel_var=-1``
was a "math domain error", a NaN level removed every track, ``rngs=[1, 2]`` compiled GRASP for
2 s before numba's TypingError, an empty team was numpy's "zero-size array"); on good arguments
they give what they gave before (the engine's unchecked bodies agree with the checked ones)."""

import json
from dataclasses import replace

import numpy as np
import pytest

from trackjam.control.assignment import SolverOptions, build_assignment, solve_assignment
from trackjam.estimation.bernoulli import Scan
from trackjam.estimation.lmb import LMBFilter, LMBParams, TrackEstimate
from trackjam.estimation.lmb_fusion import fuse_tracks, fuse_tracks_unchecked
from trackjam.metrics.ceiling import team_ceiling
from trackjam.metrics.multi import ORDER_MAX, gated_assignment, multi_track_quality, ospa_parts, ospa_series, target_classes
from trackjam.radio.antenna import AntennaModel
from trackjam.radio.measurement import target_exposure, target_exposure_unchecked
from trackjam.world.moves import displacement_set

ANT = AntennaModel(height=40.0, half_angle=np.radians(40), r0=6.0, n_e=2.0, p_d_max=0.95,
                   levels_w=np.array([0.0, 1e-5, 0.2, 1.12]), delta_w=1e-4)
LOW, HIGH = np.zeros(3), np.full(3, 100.0)
A2 = np.array([[0.0, 0, 0], [10.0, 0, 0]])
B3 = np.array([[1.0, 0, 0], [9.0, 0, 0], [50.0, 0, 0]])


def _raises(error, pattern, fn, *args, **kwargs):
    with pytest.raises(error, match=pattern):
        fn(*args, **kwargs)


# ---------------------------------------------------------------- metrics.multi


@pytest.mark.parametrize("kwargs, error, pattern", [
    (dict(c=np.nan), ValueError, r"^c: must be a finite number in \(0, 100000\], got nan"),  # scipy's error
    (dict(c=np.inf), ValueError, r"^c: must be a finite number"),  # silently inf
    (dict(c=1e300), ValueError, r"^c: must be a finite number in \(0, 100000\]"),  # OverflowError
    (dict(c=0.0), ValueError, r"^c: must be a finite number in \(0, "),
    (dict(c="10"), TypeError, r"^c: expected a number, got str"),
    (dict(c=True), TypeError, r"^c: expected a number, got bool"),
    (dict(p=1e6), ValueError, rf"^p: must be a finite number in \[1, {ORDER_MAX}\]"),  # OverflowError
    (dict(p=0.5), ValueError, r"^p: must be a finite number in \[1, "),
    (dict(p=np.nan), ValueError, r"^p: must be a finite number"),
    (dict(c=1e-200), ValueError, r"^c, p: c\^p = 1e-200\^2 is below the smallest normal float"),
])
def test_ospa_parts_refuses_bad_bounds(kwargs, error, pattern):
    _raises(error, pattern, ospa_parts, A2, B3, **kwargs)


def test_the_largest_order_cannot_overflow():
    assert 1e5 ** ORDER_MAX * 1e12 < np.finfo(float).max
    total, loc, card = ospa_parts(A2, B3, c=1e5, p=ORDER_MAX)
    assert np.isfinite([total, loc, card]).all() and 0 < total <= 1e5


@pytest.mark.parametrize("truth, estimate, error, pattern", [
    (np.ones((3, 2)), [[1, 1, 1]], ValueError, r"^truth: expected rows of 3 entries \(m, 3\).*got shape \(3, 2\)"),
    (A2, np.ones(6), ValueError, r"^estimate: expected rows of 3 entries.*got shape \(6,\)"),
    (A2, np.ones((4, 3, 1)), ValueError, r"^estimate: expected rows of 3 entries.*got shape \(4, 3, 1\)"),
    (A2, [1.0, 2.0, 3.0], ValueError, r"^estimate: expected rows of 3 entries.*got shape \(3,\)"),
    (A2 * 1j, B3, TypeError, r"^truth: expected numbers"),
    ([[np.nan, 0, 0]], B3, ValueError, r"^truth: must be finite, got NaN"),
    (A2, [[np.inf, 0, 0]], ValueError, r"^estimate: must be finite, got an infinite value"),
    (A2, [["a", "b", "c"]], TypeError, r"^estimate: expected numbers"),
])
def test_ospa_parts_refuses_what_is_not_a_point_set(truth, estimate, error, pattern):
    _raises(error, pattern, ospa_parts, truth, estimate)


def test_ospa_parts_keeps_its_values():
    """Lists, arrays, numpy numbers and 0-d arrays give the values of the formula as before."""
    d = np.minimum(np.linalg.norm(A2[:, None] - B3[None], axis=-1), 10.0) ** 2
    loc = d[0, 0] + d[1, 1]  # the least assignment: 0-1 m, 10-9 m
    want = (((loc + 100.0) / 3) ** 0.5, (loc / 3) ** 0.5, (100.0 / 3) ** 0.5)
    assert ospa_parts(A2, B3) == pytest.approx(want, rel=1e-15)
    assert ospa_parts(A2.tolist(), B3.tolist(), np.float32(10.0), np.int64(2)) == ospa_parts(A2, B3)
    assert ospa_parts(A2, B3, np.array(10.0), np.array(2.0)) == ospa_parts(A2, B3)
    assert ospa_parts([], B3, c=4.0) == ospa_parts(np.zeros((0, 3)), B3, c=4.0) == pytest.approx((4.0, 0.0, 4.0))
    assert ospa_parts([], []) == (0.0, 0.0, 0.0)
    far = ospa_parts([[1e308, 0, 0]], [[-1e308, 0, 0]], c=5.0)  # infinitely far: the cutoff
    assert far == pytest.approx((5.0, 5.0, 0.0))


@pytest.mark.parametrize("truth, positions, gate, error, pattern", [
    ([[np.inf, 0, 0], [1, 0, 0]], B3, 5, ValueError,  # was taken as undetectable
     r"^truth: each row must be a finite position or all NaN \(undetectable\), got an infinite value"),
    ([[np.nan, 0, 0], [1, 0, 0]], B3, 5, ValueError, r"^truth: each row must be .* got a row partly NaN"),
    ([[1e308, 0, 0], [0, 0, 0]], [[-1e308, 0, 0], [1, 0, 0]], 1e308, ValueError,  # scipy: infeasible
     r"^gate: must be a finite number in \(0, 100000\], got 1e\+308"),
    (A2, B3, np.nan, ValueError, r"^gate: must be a finite number"),
    (A2, B3, -1.0, ValueError, r"^gate: must be a finite number in \(0, "),
    (A2, B3, "5", TypeError, r"^gate: expected a number"),
    (np.ones(6), B3, 5, ValueError, r"^truth: expected rows of 3 entries.*got shape \(6,\)"),
    (A2, [[np.nan, 0, 0]], 5, ValueError, r"^positions: must be finite, got NaN"),
    (A2, np.ones((3, 2)), 5, ValueError, r"^positions: expected rows of 3 entries"),
])
def test_gated_assignment_refuses(truth, positions, gate, error, pattern):
    _raises(error, pattern, gated_assignment, truth, positions, gate)


def test_gated_assignment_keeps_its_values():
    truth = np.array([[0.0, 0, 0], [np.nan] * 3, [10.0, 0, 0]])
    got = gated_assignment(truth, B3, 5.0)
    assert got.tolist() == [0, -1, 1] and got.dtype == np.int64
    assert gated_assignment(truth.tolist(), B3.tolist(), np.int64(5)).tolist() == got.tolist()
    assert gated_assignment(truth, [], 5.0).tolist() == [-1, -1, -1]
    # points 1e308 apart are beyond a gate of 1e5, not a scipy error
    assert gated_assignment([[1e308, 0, 0], [0, 0, 0]], [[-1e308, 0, 0], [1, 0, 0]], 1e5).tolist() == [-1, 1]


TRUTH = np.array([[[0.0, 0, 0], [10.0, 0, 0]], [[0.0, 0, 0], [np.nan] * 3], [[1.0, 0, 0], [11.0, 0, 0]]])
EST = [(np.array(["A", "B"]), [[0.0, 0, 0], [10.0, 0, 0]]), (["B"], [[0.5, 0, 0]]), (["A", "C"], [[11.0, 0, 0], [1, 0, 0]])]


@pytest.mark.parametrize("truth, estimates, kwargs, error, pattern", [
    (TRUTH, EST[:2], {}, ValueError, r"^estimates: need one estimate per step \(3\), got 2"),
    (TRUTH, 5, {}, TypeError, r"^estimates: expected one \(labels, positions\) pair per step"),
    (TRUTH, np.zeros((3, 2)), {}, TypeError, r"^estimates: expected one \(labels, positions\) pair per step"),
    (TRUTH, EST[:2] + [(["A"], [[0.0, 0, 0]], 7)], {}, TypeError,
     r"^estimates\[2\]: expected a \(labels, positions\) pair, got 3 items"),
    (TRUTH, EST[:2] + [(["A", "B"], [[0.0, 0, 0]])], {}, ValueError, r"^estimates\[2\]: 2 labels for 1 positions"),
    (TRUTH, EST[:2] + [([["A", "B"]], [[0.0, 0, 0], [1, 0, 0]])], {}, ValueError,
     r"^estimates\[2\] labels: expected one label per position, got shape \(1, 2\)"),
    (TRUTH, EST[:2] + [(["A", "B"], np.ones(6))], {}, ValueError, r"^estimates\[2\] positions: expected rows of 3"),
    (np.where(np.isnan(TRUTH), np.inf, TRUTH), EST, {}, ValueError, r"^truth: each row must be a finite position or all NaN"),
    (TRUTH[0], EST, {}, ValueError, r"^truth: must be \(T, K, 3\), got shape \(2, 3\)"),
    (TRUTH, EST, dict(gate=np.inf), ValueError, r"^gate: must be a finite number"),
    (TRUTH, EST, dict(ids=["x"]), ValueError, r"^ids: 1 ids for 2 targets"),
    (TRUTH, EST, dict(ids=7), TypeError, r"^ids: expected one id per target"),
])
def test_multi_track_quality_refuses(truth, estimates, kwargs, error, pattern):
    _raises(error, pattern, multi_track_quality, truth, estimates, **kwargs)


def test_multi_track_quality_is_json_and_takes_any_iterable():
    q = multi_track_quality(TRUTH, EST, 5.0, ids=[np.int64(7), np.int64(8)])
    assert all(type(v) is int for v in q["label_switches"]) and q["label_switches"] == [2, 1]  # A, B, C; B, A
    assert q["ids"] == [7, 8] and all(type(v) is int for v in q["ids"])
    json.dumps(q)
    assert multi_track_quality(TRUTH, (e for e in EST), 5.0, ids=[7, 8]) == q
    assert multi_track_quality(TRUTH, tuple(EST), 5.0, ids=[7, 8]) == q
    np.testing.assert_array_equal(ospa_series(TRUTH, iter(EST)), ospa_series(TRUTH, EST))
    classes, false_tracks, _ = target_classes(TRUTH, map(tuple, EST), 5.0)
    assert classes.tolist() == [[0, 0], [0, 2], [0, 0]] and false_tracks.tolist() == [0, 0, 0]


def test_ospa_series_checks_its_bounds_once_before_any_step():
    _raises(ValueError, r"^c: must be a finite number", ospa_series, TRUTH, EST, c=-1.0)
    _raises(ValueError, r"^p: must be a finite number", ospa_series, TRUTH, EST, p=0.0)


# ---------------------------------------------------------------- metrics.ceiling


def test_team_ceiling_needs_an_agent():
    _raises(ValueError, r"^initial: the team needs at least one agent, got shape \(0, 3\)",
            team_ceiling, np.zeros((3, 2, 3)), np.ones((3, 2), bool), np.zeros((0, 3)), 5, [0, 0, 0], [100, 100, 100])


# ---------------------------------------------------------------- radio.measurement.target_exposure

XK = np.array([[52.0, 51.0, 55.0], [40.0, 45.0, 48.0]])
UN = np.array([[50.0, 50.0, 50.0], [45.0, 45.0, 45.0], [60.0, 60.0, 40.0]])
AIMS = np.array([[52.0, 51.0, 55.0], [40.0, 45.0, 48.0], [50.0, 50.0, 50.0]])
LEVELS = np.array([1.12, 0.2, 0.0])
GOOD = (XK, [True, True], [True, False], UN, AIMS, LEVELS, ANT)


def _exposure(**changed):
    names = ("X", "exists", "detectable", "u", "aim", "level_w", "ant")
    return tuple(changed.get(k, v) for k, v in zip(names, GOOD))


@pytest.mark.parametrize("changed, error, pattern", [
    (dict(exists=[True]), ValueError, r"^exists: expected one entry per target \(2\), got shape \(1,\)"),
    (dict(exists=[True, True, False]), ValueError, r"^exists: expected one entry per target \(2\), got shape \(3,\)"),
    (dict(detectable=True), ValueError, r"^detectable: expected one entry per target \(2\), got shape \(\)"),
    (dict(exists=[0.5, 1.0]), TypeError, r"^exists: expected booleans \(or 0 and 1\), one per target, got float64"),
    (dict(exists=[np.nan, 1.0]), TypeError, r"^exists: expected booleans"),
    (dict(detectable=[2, 0]), ValueError, r"^detectable: expected booleans \(or 0 and 1\), got \[2, 0\]"),
    (dict(detectable=["yes", "no"]), TypeError, r"^detectable: expected booleans"),
    (dict(level_w=LEVELS[:2]), ValueError, r"^level_w: expected one level per agent \(3\), got shape \(2,\)"),
    (dict(level_w=1.12), ValueError, r"^level_w: expected one level per agent \(3\), got shape \(\)"),
    (dict(level_w=[1.12, np.nan, 0]), ValueError, r"^level_w: must be finite numbers in \[0, 1.12\], got .*nan"),
    (dict(level_w=[1.12, 5.0, 0]), ValueError, r"^level_w: must be finite numbers in \[0, 1.12\], got .*5\.0"),
    (dict(u=UN[0]), ValueError, r"^u: expected rows of 3 entries"),  # was an IndexError
    (dict(u=np.where(UN == 45.0, np.nan, UN)), ValueError, r"^u: must be finite, got NaN"),
    (dict(aim=AIMS[:2]), ValueError, r"^aim: expected one aim per agent as u has \(3, 3\), got shape \(2, 3\)"),
    (dict(aim=np.full((3, 3), np.inf)), ValueError, r"^aim: must be finite"),
    (dict(X=XK.ravel()), ValueError, r"^X: expected rows of 3 entries \(K, 3\), one per target, got shape \(6,\)"),
    (dict(X=[[52.0, 51.0, np.nan], [40.0, 45.0, 48.0]]), ValueError, r"^X: a present target's row \(exists True\) must be finite"),
    (dict(X=XK * 1j), TypeError, r"^X: expected numbers"),
    (dict(ant="antenna"), TypeError, r"^ant: expected an AntennaModel, got str"),
])
def test_target_exposure_refuses(changed, error, pattern):
    _raises(error, pattern, target_exposure, *_exposure(**changed))


def test_target_exposure_keeps_its_values():
    want = target_exposure_unchecked(*GOOD)
    for args in (GOOD, _exposure(X=XK.tolist(), exists=[1, 1], detectable=np.array([1, 0]), u=UN.tolist(),
                                 aim=AIMS.tolist(), level_w=LEVELS.tolist())):
        got = target_exposure(*args)
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)
    # an absent target's row is not read: NaN there (the engine's nan_to_num gives 0) changes nothing
    absent = _exposure(X=[[52.0, 51.0, 55.0], [np.nan] * 3], exists=[True, False])
    for g, w in zip(target_exposure(*absent), target_exposure_unchecked(*_exposure(X=[[52.0, 51.0, 55.0], [0.0] * 3],
                                                                                   exists=[True, False]))):
        np.testing.assert_array_equal(g, w)
    assert all(a.shape == (3, 0) for a in target_exposure(np.zeros((0, 3)), [], [], UN, AIMS, LEVELS, ANT))


# ---------------------------------------------------------------- estimation.lmb_fusion.fuse_tracks


def _track(label, e, pos, std=1.0):
    return TrackEstimate(label, e, np.array([*pos, 0.0, 0.0, 0.0]), np.diag([std**2] * 3 + [0.5] * 3))


TRACKS = [[_track((1, 0), 0.9, [10, 10, 10]), _track((1, 1), 0.3, [50, 50, 50])],
          [_track((2, 0), 0.8, [10.5, 10, 10])], []]
PREDICTED = [[0.85, 0.3], [0.7], []]


def _changed(a, i, **kw):
    out = [list(mine) for mine in TRACKS]
    out[a][i] = replace(out[a][i], **kw)
    return out


@pytest.mark.parametrize("args, kwargs, error, pattern", [
    ((_changed(0, 1, existence=np.nan),), {}, ValueError, r"^tracks\[0\]\[1\]\.existence: must be a finite number in \[0, 1\], got nan"),
    ((_changed(1, 0, existence=2.0),), {}, ValueError, r"^tracks\[1\]\[0\]\.existence: must be a finite number in \[0, 1\]"),
    ((_changed(1, 0, existence="0.5"),), {}, TypeError, r"^tracks\[1\]\[0\]\.existence: expected a number"),
    ((_changed(1, 0, cov=-np.eye(6)),), {}, ValueError, r"^tracks\[1\]\[0\]\.cov: must be positive semi-definite"),
    ((_changed(0, 0, cov=np.triu(np.ones((6, 6)))),), {}, ValueError, r"^tracks\[0\]\[0\]\.cov: must be symmetric"),
    ((_changed(0, 0, cov=np.eye(3)),), {}, ValueError, r"^tracks\[0\]\[0\]\.cov: expected a \(6, 6\) matrix"),
    ((_changed(1, 0, mean=np.zeros(4)),), {}, ValueError, r"^tracks\[1\]\[0\]\.mean: expected a vector of 6 entries, got shape \(4,\)"),
    ((_changed(0, 0, mean=np.full(6, np.nan)),), {}, ValueError, r"^tracks\[0\]\[0\]\.mean: must be finite"),
    (([[TrackEstimate((1, 0), 0.5, np.zeros(2), np.eye(2))]],), {}, ValueError, r"^tracks\[0\]\[0\]\.mean: expected at least 3 entries"),
    ((TRACKS,), dict(rule="evidence"), ValueError, r"^predicted: rule 'evidence' needs every track's predicted existence"),
    ((TRACKS,), dict(rule="vote"), ValueError, r"^rule: must be one of mean, evidence, got 'vote'"),
    ((TRACKS, [[0.85, 0.3], [np.nan], []], "evidence"), {}, ValueError, r"^predicted\[1\]: must be finite"),
    ((TRACKS, [[0.85, 0.3], [1.5], []], "evidence"), {}, ValueError, r"^predicted\[1\]: must lie in \[0, 1\]"),
    ((TRACKS, [[0.85], [0.7], []], "evidence"), {}, ValueError, r"^predicted\[0\]: expected a vector of 2 entries"),
    ((TRACKS, [[0.85, 0.3], [0.7]], "evidence"), {}, ValueError, r"^predicted: expected one list per agent \(3\), got 2"),
    ((TRACKS,), dict(gate=np.nan), ValueError, r"^gate: must be a finite number in \(0, 1e\+100\], got nan"),
    ((TRACKS,), dict(gate=-1.0), ValueError, r"^gate: must be a finite number in \(0, "),
    ((TRACKS,), dict(gate=0.0), ValueError, r"^gate: must be a finite number in \(0, "),
    ((None,), {}, TypeError, r"^tracks: expected one list of TrackEstimate per agent, got NoneType"),
    (([TRACKS[0], 5],), {}, TypeError, r"^tracks\[1\]: expected a list of TrackEstimate, got int"),
    (([[(1, 0)]],), {}, TypeError, r"^tracks\[0\]\[0\]: expected a TrackEstimate"),
])
def test_fuse_tracks_refuses(args, kwargs, error, pattern):
    _raises(error, pattern, fuse_tracks, *args, **kwargs)


@pytest.mark.parametrize("predicted, rule", [(None, "mean"), (PREDICTED, "mean"), (PREDICTED, "evidence")])
def test_fuse_tracks_keeps_its_values(predicted, rule):
    want = fuse_tracks_unchecked(TRACKS, predicted, rule)
    got = fuse_tracks([tuple(mine) for mine in TRACKS], predicted, rule, gate=np.int64(16))
    assert [f.members for f in got] == [f.members for f in want] and len(got) == 2
    for g, w in zip(got, want):
        assert g.estimate.existence == w.estimate.existence
        np.testing.assert_array_equal(g.estimate.weights, w.estimate.weights)
        if w.estimate.mean is not None:
            np.testing.assert_array_equal(g.estimate.mean, w.estimate.mean)
            np.testing.assert_array_equal(g.estimate.cov, w.estimate.cov)
    assert fuse_tracks([[], []]) == []
    # a collapsed track (all particles on one point: a zero covariance) is positive semi-definite
    assert len(fuse_tracks([[replace(TRACKS[0][0], cov=np.zeros((6, 6)))], TRACKS[1]])) == 1


# ---------------------------------------------------------------- estimation.lmb

BASE = dict(survival_prob=0.98, particles=200, birth_particles=100, birth_rate=0.1, birth_existence_max=0.1,
            birth_speed=3.0, accel_var=0.5, walls="reflect", low=LOW, high=HIGH,
            noise_std=np.array([0.8, 0.0628, 0.0628]), clutter_rate=5.0)


@pytest.mark.parametrize("changed, error, pattern", [
    (dict(accel_var=-1.0), ValueError, r"^accel_var: must be a finite number in \[0, 10000\], got -1.0"),  # math domain error
    (dict(accel_var=np.nan), ValueError, r"^accel_var: must be a finite number"),
    (dict(noise_std=[0.0, 0.0, 0.0]), ValueError, r"^noise_std: the standard deviations must be > 0"),  # ZeroDivisionError
    (dict(noise_std=[0.8, np.nan, 0.1]), ValueError, r"^noise_std: must be finite"),
    (dict(noise_std=[0.8]), ValueError, r"^noise_std: expected a vector of 3 entries"),
    (dict(clutter_rate=-1.0), ValueError, r"^clutter_rate: must be a finite number in \[0, 1000\]"),  # existence 1.0
    (dict(clutter_rate=np.nan), ValueError, r"^clutter_rate: must be a finite number"),
    (dict(birth_rate=np.nan), ValueError, r"^birth_rate: must be a finite number in \[0, 1000\]"),
    (dict(birth_rate=-0.1), ValueError, r"^birth_rate: must be a finite number"),
    (dict(birth_speed=np.nan), ValueError, r"^birth_speed: must be a finite number in \[0, 1000\]"),
    (dict(birth_existence_max=1.0), ValueError, r"^birth_existence_max: must lie in \(0, 1\), got 1.0"),
    (dict(birth_existence_max=np.nan), ValueError, r"^birth_existence_max: must be a finite number"),
    (dict(survival_prob=1.5), ValueError, r"^survival_prob: must be a finite number in \[0, 1\]"),
    (dict(low=np.array([0.0, 0.0, np.nan])), ValueError, r"^low: must be finite"),
    (dict(low=HIGH, high=LOW), ValueError, r"^low, high: the area's low corner must lie below its high one"),
    (dict(prune=np.nan), ValueError, r"^prune: must be a finite number in \[0, 1\]"),
    (dict(prune=-0.1), ValueError, r"^prune: must be a finite number in \[0, 1\]"),
    (dict(gibbs_samples=10**12), ValueError, r"^gibbs_samples: must lie in \[1, 1000000\]"),  # MemoryError
    (dict(gibbs_samples=10.0), TypeError, r"^gibbs_samples: expected a whole number"),
    (dict(particles=10**9), ValueError, r"^particles: must lie in \[1, 10000000\]"),  # accepted
    (dict(particles=0), ValueError, r"^particles: must lie in \[1, "),
    (dict(birth_particles=1.5), TypeError, r"^birth_particles: expected a whole number"),
    (dict(max_tracks=0), ValueError, r"^max_tracks: must lie in \[1, 1000\]"),
    (dict(ranked_k=10**9), ValueError, r"^ranked_k: must lie in \[1, 10000\]"),
    (dict(association="best"), ValueError, r"^association: expected 'gibbs' or 'ranked', got 'best'"),
    (dict(walls="bounce"), ValueError, r"^walls: expected 'reflect' or 'none', got 'bounce'"),
    (dict(visibility=(0.1, np.nan)), ValueError, r"^visibility reappear: must be a finite number in \[0, 1\]"),
    (dict(visibility=(0.1,)), ValueError, r"^visibility: expected \(hide, reappear\)"),
    (dict(response="stop"), TypeError, r"^response: expected a FailSafe or None, got str"),
])
def test_lmb_params_check_every_field(changed, error, pattern):
    _raises(error, pattern, LMBParams, **{**BASE, **changed})


def test_lmb_params_take_numpy_numbers_and_a_few_particles():
    p = LMBParams(**{**BASE, "particles": np.int64(4), "birth_particles": 4, "accel_var": np.float32(0.5),
                     "clutter_rate": np.array(5.0), "prune": 1e-12, "visibility": (0.05, 0.25)})
    assert p.particles == 4 and p.birth_particles == 4 and p.prune == 1e-12
    assert p.accel_var == 0.5 and float(p.clutter_rate) == 5.0 and tuple(p.visibility) == (0.05, 0.25)


U = np.array([10.0, 10.0, 10.0])
AIM = np.array([14.0, 13.0, 12.0])
Z = np.array([[5.0, 0.6, 1.0], [20.0, -1.0, 2.0]])


def _filter(seed=0):
    return LMBFilter(LMBParams(**BASE), ANT, np.random.default_rng(seed))


@pytest.mark.parametrize("args, error, pattern", [
    ((Z, [np.nan, 0, 0], AIM, 1.12), ValueError, r"^u: must be finite"),  # removed every track
    ((Z, U, [np.inf, 0, 0], 1.12), ValueError, r"^aim: must be finite"),
    ((Z, U, AIM, np.nan), ValueError, r"^level_w: must be a finite number in \[0, 1.12\], got nan"),  # removed every track
    ((Z, U, AIM, np.inf), ValueError, r"^level_w: must be a finite number"),  # scipy error
    ((Z, U, AIM, 5.0), ValueError, r"^level_w: must be a finite number in \[0, 1.12\], got 5.0"),
    ((Z, U, AIM, "1"), TypeError, r"^level_w: expected a number"),
    ((np.ones((3, 2)), U, AIM, 1.12), ValueError, r"^Z: expected rows of 3 entries \(m, 3\).*got shape \(3, 2\)"),
    ((np.ones(6), U, AIM, 1.12), ValueError, r"^Z: expected rows of 3 entries \(m, 3\).*got shape \(6,\)"),
    (([[5.0, np.nan, 1.0]], U, AIM, 1.12), ValueError, r"^Z: must be finite, got NaN"),
    (([[np.inf, 0.0, 1.0]], U, AIM, 1.12), ValueError, r"^Z: must be finite, got an infinite value"),
    (([[-20.0, 0.0, 1.0]], U, AIM, 1.12), ValueError, r"^Z: a range \(first entry\) below -11 range deviations \(-8.8 m\)"),
    ((Z * 1j, U, AIM, 1.12), TypeError, r"^Z: expected numbers"),
    ((Z, U[:2], AIM, 1.12), ValueError, r"^u: expected a vector of 3 entries"),
    ((Z, U, AIM, 1.12, [Z]), TypeError, r"^others\[0\]: expected a Scan"),
    ((Z, U, AIM, 1.12, 5), TypeError, r"^others: expected a list of the teammates' Scans, got int"),
])
def test_lmb_update_refuses_before_any_work(args, error, pattern):
    f = _filter()
    f.predict()
    before = (f.step, list(f.tracks), f.rng.bit_generator.state)
    _raises(error, pattern, f.update, *args)
    assert (f.step, list(f.tracks), f.rng.bit_generator.state) == before


def _run(updates):
    f = _filter(3)
    out = []
    for args in updates:
        f.predict()
        out.append(f.update(*args))
    return out


def test_lmb_update_keeps_its_values():
    """Lists, numpy numbers, an empty scan and a small negative range (the sensor's noise near the
    agent) are taken as before: the same estimates as the arrays give."""
    arrays = [(Z, U, AIM, 1.12), (np.zeros((0, 3)), U, AIM, 0.2), (np.array([[-0.5, 0.6, 1.0]]), U, AIM, 1.12)]
    loose = [(Z.tolist(), U.tolist(), tuple(AIM), np.float64(1.12)), ([], U, AIM, np.float64(0.2)),
             ([[-0.5, 0.6, 1.0]], U, AIM, np.array(1.12))]
    for a, b in zip(_run(arrays), _run(loose)):
        assert [(t.label, t.existence) for t in a] == [(t.label, t.existence) for t in b]
        for s, t in zip(a, b):
            np.testing.assert_array_equal(s.mean, t.mean)
    others = [Scan.of(Z, U + 1.0, AIM, 1.12, ANT)]
    listed, generated, alone = (_run([(Z, U, AIM, 1.12), (Z, U, AIM, 1.12, *o)])[1]
                                for o in ((others,), ((sc for sc in others),), ()))
    assert [(t.label, t.existence) for t in listed] == [(t.label, t.existence) for t in generated]
    assert listed and [t.existence for t in listed] != [t.existence for t in alone]  # the teammate's scan counted


# ---------------------------------------------------------------- control.assignment


@pytest.fixture(scope="module")
def problem():
    D = displacement_set([4.0], 4, 4)
    u = np.array([[40.0, 40.0, 40.0], [60.0, 60.0, 40.0]])
    aims = np.array([[45.0, 45.0, 45.0], [55.0, 55.0, 45.0]])
    return build_assignment(u, aims, D, ANT, LOW, HIGH, 1, True, "sum")


def _rngs(n=2):
    return [np.random.default_rng([7, j]) for j in range(n)]


@pytest.mark.parametrize("call, error, pattern", [
    (lambda P: solve_assignment(P, "greedy", None), TypeError, r"^rngs: expected a list of numpy Generators, one per agent, got NoneType"),
    (lambda P: solve_assignment(P, "grasp", [1, 2]), TypeError, r"^rngs\[0\]: expected a numpy Generator"),  # numba TypingError after 2 s
    (lambda P: solve_assignment(P, "grasp", _rngs(1)), ValueError, r"^rngs: grasp draws from one generator per agent \(2\), got 1"),
    (lambda P: solve_assignment(P, "grasp", np.random.default_rng(0)), TypeError, r"^rngs: expected a list of numpy Generators"),
    (lambda P: solve_assignment(P, ["exact"], []), TypeError, r"^solver: expected a solver's name"),  # unhashable type
    (lambda P: solve_assignment(P, "astar", []), ValueError, r"^solver: unknown solver 'astar'; expected one of greedy, grasp, exact"),
    (lambda P: solve_assignment(P, "exact", [], {"time_limit_s": 1.0}), TypeError, r"^options: expected a SolverOptions"),  # AttributeError
    (lambda P: solve_assignment(None, "greedy", []), TypeError, r"^problem: expected an AssignmentProblem"),  # AttributeError
])
def test_solve_assignment_refuses(problem, call, error, pattern):
    _raises(error, pattern, call, problem)


def test_solve_assignment_keeps_its_values(problem):
    options = SolverOptions(samples=50, iterations=3)
    a = solve_assignment(problem, "grasp", _rngs(), options)
    b = solve_assignment(problem, "grasp", tuple(_rngs()), options)
    c = solve_assignment(problem, "grasp", (r for r in _rngs()), options)
    for s in (b, c):
        assert (s.objective, list(s.move), list(s.level), list(s.target)) == (a.objective, list(a.move), list(a.level), list(a.target))
    assert solve_assignment(problem, "greedy", []).objective == solve_assignment(problem, "greedy", _rngs()).objective
    assert solve_assignment(problem, "exact", ()).optimal

