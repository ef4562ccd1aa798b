"""The per-call functions of the library's pieces used alone (Eqs. 7, 9, 10, 13, the scan, the
fusion, the problem and the ceiling) refuse bad arrays with one exception naming the argument
(a fuzz hunt of the Python API: a negative level gave a negative p_D, h of a transposed array
measured its columns, fuse took a negative-definite covariance, a flat (2T, 3) truth passed for
(T, 6)); on good arrays they give what they gave before, so the engine's runs do not change."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.solve import build_problem
from trackjam.estimation.bernoulli import Estimate
from trackjam.estimation.fusion import covariance_intersection, fuse, fuse_unchecked
from trackjam.metrics.ceiling import chase, clairvoyant_ceiling
from trackjam.radio.antenna import AntennaModel, cone_gain, detection_probability, interference_matrix, received_power
from trackjam.radio.measurement import h, h_inverse, sample_scan
from trackjam.world.moves import displacement_set

ANT = AntennaModel(height=40.0, half_angle=np.radians(40), r0=6.0, n_e=2.0, p_d_max=0.95,
                   levels_w=np.array([0.0, 1e-5, 0.2, 1.12]), delta_w=1e-4)
U = np.array([50.0, 50.0, 50.0])
X = np.array([52.0, 51.0, 55.0])
LOW, HIGH = np.zeros(3), np.full(3, 100.0)
NAN3 = np.array([np.nan, 1.0, 1.0])
NOISE = np.array([0.8, 0.0628, 0.0628])


def _raises(error, words, fn, *args, **kwargs):
    with pytest.raises(error) as err:
        fn(*args, **kwargs)
    assert str(err.value).startswith(words), str(err.value)


@pytest.mark.parametrize("args, error, words", [
    ((X, U, X, -1.0), ValueError, "level_w: must be finite numbers in [0, 1.12]"),  # gave p_D -0.85
    ((X, U, X, 5.0), ValueError, "level_w: must be finite numbers in [0, 1.12]"),  # gave p_D 4.2
    ((X, U, X, np.nan), ValueError, "level_w: must be finite numbers"),
    ((NAN3, U, X, 1.12), ValueError, "x: must be finite, got NaN"),
    ((X, U, [np.inf, 0, 0], 1.12), ValueError, "aim: must be finite, got an infinite value"),
    ((X[:2], U, X, 1.12), ValueError, "x: expected an array of 3 entries"),
    ((np.ones((4, 3)), np.ones((5, 3)), X, 1.12), ValueError,
     "x, u, aim, level_w: shapes do not broadcast together: x (4, 3), u (5, 3), aim (3,), level_w ()"),
    ((np.ones((4, 3)), U, X, np.ones(3)), ValueError, "x, u, aim, level_w: shapes do not broadcast together"),
    ((X, U, "here", 1.12), TypeError, "aim: expected numbers, got str"),
])
def test_detection_probability_refuses_bad_arrays(args, error, words):
    _raises(error, words, detection_probability, *args, ANT)


def test_received_power_takes_any_level_at_or_above_zero_and_refuses_the_rest():
    assert float(received_power(X, U, X, 5.0, ANT)) == pytest.approx(5.0 * float(cone_gain(X, U, X, ANT)))
    _raises(ValueError, "level_w: must be finite numbers in [0, inf)", received_power, X, U, X, -1e-9, ANT)
    _raises(TypeError, "ant: expected an AntennaModel, got dict", received_power, X, U, X, 1.0, {"height": 40})


def test_interference_matrix_refuses_rows_that_do_not_match():
    u = np.array([[10.0, 10, 10], [20, 20, 20], [30, 30, 30]])
    _raises(ValueError, "positions, aims, levels_w: expected shapes (3, 3), (3, 3) and (3,)",
            interference_matrix, u, u[:2], np.ones(3), ANT)
    _raises(ValueError, "positions, aims, levels_w: expected shapes", interference_matrix, u, u, np.ones(2), ANT)
    _raises(ValueError, "aims: must be finite", interference_matrix, u, np.where(u > 25, np.nan, u), np.ones(3), ANT)
    _raises(ValueError, "positions: expected rows of 3 entries", interference_matrix, u[0], u, np.ones(3), ANT)
    _raises(ValueError, "levels_w: must be finite numbers in [0, inf)", interference_matrix, u, u, -np.ones(3), ANT)


@pytest.mark.parametrize("x, u, words", [
    (np.ones((3, 5)), U, "x: expected an array of 3 or 6 entries"),  # a transposed array: h measured its columns
    (NAN3, U, "x: must be finite"),
    (X, np.ones(6), "u: expected an array of 3 entries"),
    (np.ones((4, 3)), np.ones((2, 3)), "x, u: shapes do not broadcast together"),
])
def test_h_refuses_what_is_not_positions(x, u, words):
    _raises(ValueError, words, h, x, u)


def test_h_takes_a_state_whose_velocity_is_not_known():
    np.testing.assert_array_equal(h(np.r_[X, np.nan, 0.0, 0.0], U), h(X, U))


@pytest.mark.parametrize("value, words", [
    (np.array([1.0, 2.0, 3.0]) + 1j, "x: expected numbers, got ndarray"),  # the imaginary part was dropped
    (np.array([True, False, True]), "x: expected numbers, got ndarray"),
    (["52", "51", "55"], "x: expected numbers, got list"),
    ([[1.0, 2.0, 3.0], [1.0]], "x: expected numbers in a regular array"),
])
def test_h_refuses_what_is_not_numbers(value, words):
    _raises(TypeError, words, h, value, U)


def test_a_broadcast_too_large_for_memory_is_refused_before_it_is_made():
    _raises(ValueError, "x, u: together they make 10,000,000,000 entries", h, np.zeros((100_000, 1, 3)),
            np.zeros((1, 100_000, 3)))


def test_h_inverse_refuses_a_negative_range_and_undoes_h():
    _raises(ValueError, "z: its range rho (first entry) must be >= 0", h_inverse, [-1.0, 0.0, 1.0], U)
    _raises(ValueError, "z: must be finite", h_inverse, [1.0, np.nan, 1.0], U)
    np.testing.assert_allclose(h_inverse(h(X, U), U), X, atol=1e-12)


@pytest.mark.parametrize("changed, error, words", [
    ({"p_d": 1.5}, ValueError, "p_d: must be a finite number in [0, 1]"),
    ({"p_d": np.nan}, ValueError, "p_d: must be a finite number in [0, 1]"),
    ({"clutter_rate": 1e12}, ValueError, "clutter_rate: must be a finite number in [0, 1000]"),  # would not fit in memory
    ({"clutter_rate": -1.0}, ValueError, "clutter_rate: must be a finite number in [0, 1000]"),
    ({"noise_std": [0.8, 0.1]}, ValueError, "noise_std: expected one deviation > 0 or 3 of them"),
    ({"noise_std": [0.8, -0.1, 0.1]}, ValueError, "noise_std: must be finite numbers in [0, inf)"),
    ({"noise_std": [0.8, 0.0, 0.1]}, ValueError, "noise_std: expected one deviation > 0 or 3 of them"),
    ({"max_range": 0.0}, ValueError, "max_range: must be a finite number in (0, inf)"),
    ({"x": NAN3}, ValueError, "x: must be finite"),
    ({"x": np.ones((2, 3))}, ValueError, "x: expected a vector of 3 or 6 entries"),
    ({"u": [1.0, 2.0]}, ValueError, "u: expected a vector of 3 entries"),
    ({"rng": 7}, TypeError, "rng: expected a numpy Generator"),
])
def test_sample_scan_refuses_bad_arguments_before_any_draw(changed, error, words):
    args = dict(rng=np.random.default_rng(0), x=X, u=U, p_d=0.5, noise_std=NOISE, clutter_rate=3.0, max_range=52.2)
    args |= changed
    _raises(error, words, sample_scan, *args.values())


def test_sample_scan_takes_what_it_took_before_the_checks():
    """0-d arrays for numbers, one deviation for all three, a legacy RandomState, a state."""
    Z, _ = sample_scan(np.random.default_rng(1), np.r_[X, np.nan, 0, 0], U, np.array(0.5), 0.5, 3.0, np.array(52.2))
    Z0, _ = sample_scan(np.random.default_rng(1), X, U, 0.5, np.full(3, 0.5), 3.0, 52.2)
    np.testing.assert_array_equal(Z, Z0)
    assert sample_scan(np.random.RandomState(1), X, U, 0.5, NOISE, 3.0, 52.2)[0].shape[1] == 3


def test_sample_scan_draws_nothing_when_it_refuses_and_the_same_scan_when_it_takes():
    rng = np.random.default_rng(3)
    with pytest.raises(ValueError):
        sample_scan(rng, X, U, 2.0, NOISE, 3.0, 52.2)
    Z, _ = sample_scan(rng, X, U, 0.9, NOISE, 3.0, 52.2)
    Z0, _ = sample_scan(np.random.default_rng(3), X, U, 0.9, NOISE, 3.0, 52.2)
    np.testing.assert_array_equal(Z, Z0)


def _estimate(e=0.9, mean=None, cov=None):
    return Estimate(e, np.arange(6.0) if mean is None else mean, np.eye(6) if cov is None else cov)


NEG = np.diag([1.0, 1, 1, 1, 1, -1])
ASYM = np.eye(6) + np.triu(np.ones((6, 6)), 1)


@pytest.mark.parametrize("estimates, kwargs, error, words", [
    ([_estimate(cov=NEG)], {}, ValueError, "estimates[0].cov: must be positive semi-definite"),  # was fused
    ([_estimate(), _estimate(cov=ASYM)], {}, ValueError, "estimates[1].cov: must be symmetric"),
    ([_estimate(cov=np.eye(3))], {}, ValueError, "estimates[0].cov: expected a (6, 6) matrix"),
    ([_estimate(mean=np.full(6, np.nan))], {}, ValueError, "estimates[0].mean: must be finite"),
    ([_estimate(), _estimate(mean=np.zeros(3))], {}, ValueError, "estimates[1].mean: expected a vector of 6 entries"),
    ([_estimate(e=1.5)], {}, ValueError, "estimates[0].existence: must be a finite number in [0, 1]"),
    ([_estimate(e=np.nan)], {}, ValueError, "estimates[0].existence: must be a finite number in [0, 1]"),
    ([], {}, ValueError, "estimates: fuse needs at least one estimate"),
    ([(0.9, np.zeros(6))], {}, TypeError, "estimates[0]: expected an Estimate"),
    ([_estimate()], {"rule": "median"}, ValueError, "rule: must be one of mean, evidence"),
    ([_estimate()], {"rule": "evidence"}, ValueError, "predicted: rule 'evidence' needs"),
    ([_estimate()], {"predicted": [0.5, 0.5]}, ValueError, "predicted: expected one entry per estimate (1), got 2"),
    ([_estimate()], {"predicted": [1.5]}, ValueError, "predicted: must lie in [0, 1]"),
    ([_estimate()], {"rule": "evidence", "predicted": [0.5], "log_evidence": [0.1]}, ValueError,
     "log_evidence, visibility: give both"),
    ([_estimate()], {"rule": "evidence", "predicted": [0.5], "log_evidence": [np.nan], "visibility": [0.5]},
     ValueError, "log_evidence: expected a vector of numbers below +inf"),
])
def test_fuse_refuses_what_is_not_a_set_of_estimates(estimates, kwargs, error, words):
    _raises(error, words, fuse, estimates, **kwargs)


def test_fuse_takes_a_0d_existence_and_a_covariance_asymmetric_by_rounding():
    C = np.eye(6)
    C[0, 1] += 1e-7
    assert fuse([_estimate(e=np.array(0.9), cov=C)]).existence == pytest.approx(0.9)


def test_fuse_refuses_a_log_evidence_that_is_not_numbers():
    _raises(TypeError, "log_evidence: expected numbers, got dict", fuse, [_estimate()], [0.5], "evidence",
            {"a": 1.0}, [0.5])


def test_fuse_takes_rounding_below_zero_and_a_log_evidence_of_minus_infinity():
    C = np.diag([1.0, 1, 1, 1, 1, -1e-13])  # a mode cluster without spread, rounded
    fused = fuse([_estimate(cov=C), _estimate()], predicted=[0.5, 0.5], rule="evidence",
                 log_evidence=[-np.inf, 0.0], visibility=[0.5, 0.5])
    assert fused.mean is not None and np.all(np.isfinite(fused.mean))


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(0, 2**32 - 1)), min_size=1, max_size=4),
       st.sampled_from(["mean", "evidence"]))
def test_fuse_gives_what_the_engines_unchecked_fuse_gives(agents, rule):
    estimates, predicted = [], []
    for e, seed in agents:
        rng = np.random.default_rng(seed)
        A = rng.normal(size=(6, 6))
        estimates.append(Estimate(e, rng.normal(50, 10, 6), A @ A.T + 0.1 * np.eye(6)))
        predicted.append(float(rng.uniform()))
    checked = fuse(estimates, predicted, rule)
    plain = fuse_unchecked(estimates, predicted, rule)
    assert checked.existence == plain.existence
    np.testing.assert_array_equal(checked.weights, plain.weights)
    if plain.mean is None:
        assert checked.mean is None
    else:
        np.testing.assert_array_equal(checked.mean, plain.mean)
        np.testing.assert_array_equal(checked.cov, plain.cov)


def test_covariance_intersection_of_one_estimate_is_that_estimate():
    C = np.diag([1.0, 2, 3, 4, 5, 6])
    mean, cov, omega = covariance_intersection([np.arange(6.0)], [C])
    np.testing.assert_allclose(mean, np.arange(6.0))
    np.testing.assert_allclose(cov, C)
    assert omega.tolist() == [1.0]


D = displacement_set([1.0, 5.0], 8, 5)
POS = np.array([[10.0, 10, 10], [20, 20, 20], [30, 30, 30]])


@pytest.mark.parametrize("changed, error, words", [
    ({"aim": [np.nan, 50.0, 50.0]}, ValueError, "aim: must be finite"),  # gave NaN gains
    ({"aim": [50.0, 50.0]}, ValueError, "aim: expected an array of 3 entries"),
    ({"aim": np.ones((2, 3))}, ValueError, "aim: expected one point of 3 entries"),
    ({"positions": np.ones((3, 2))}, ValueError, "positions: expected an array of 3 entries"),
    ({"displacements": D[:, :2]}, ValueError, "displacements: expected rows of 3 entries"),
    ({"low": HIGH, "high": LOW}, ValueError, "low, high: the area's low corner must lie below its high one"),
    ({"high": [100.0, 100.0, np.inf]}, ValueError, "high: must be finite"),
    ({"at_least": True}, TypeError, "at_least: expected a whole number in [1, 3], got bool"),
    ({"at_least": 4}, ValueError, "at_least: must lie in [1, 3], got 4"),
    ({"antenna": None}, TypeError, "antenna: expected an AntennaModel, got NoneType"),
])
def test_build_problem_refuses_bad_arguments(changed, error, words):
    args = dict(positions=POS, aim=[50.0, 50.0, 50.0], displacements=D, antenna=ANT, low=LOW, high=HIGH,
                at_least=2, constraints=True) | changed
    _raises(error, words, build_problem, **args)


def test_build_problem_takes_what_it_took_before_the_checks():
    args = dict(positions=POS, displacements=D, antenna=ANT, constraints=True)
    plain = build_problem(aim=[50.0, 50.0, 50.0], low=LOW, high=HIGH, at_least=2, **args)
    loose = build_problem(aim=[[50.0, 50.0, 50.0]], low=0.0, high=100.0, at_least=2.0, **args)
    np.testing.assert_array_equal(plain.p_d, loose.p_d)
    np.testing.assert_array_equal(plain.gain, loose.gain)
    assert loose.at_least == 2


def test_build_problem_names_the_positions_outside_the_area_and_a_first_control_that_moves():
    args = dict(aim=[50.0, 50.0, 50.0], antenna=ANT, low=LOW, high=HIGH, at_least=2, constraints=True)
    _raises(ValueError, "positions: every agent must lie inside the area [0.0, 0.0, 0.0] to [100.0, 100.0, 100.0]",
            build_problem, positions=POS - 20.0, displacements=D, **args)
    _raises(ValueError, "displacements: control 0 of the displacement set must be hover",
            build_problem, positions=POS, displacements=D[1:], **args)


def _line(xs):
    return np.array([[x, 50.0, 50.0] for x in xs])


@pytest.mark.parametrize("args, error, words", [
    ((np.ones((3, 6)), [True] * 3), ValueError, "truth, detectable: need truth (T, 3)"),  # read as (6, 3) before
    ((_line([1.0, 2.0]), ["False", "True"]), ValueError, "detectable: expected booleans"),  # 'False' was detectable
    ((_line([1.0, 2.0]), [0, 2]), ValueError, "detectable: expected booleans (or 0 and 1)"),
    ((np.array([["a", "b", "c"]]), [False]), TypeError, "truth: expected numbers"),
    ((_line([1.0, 2.0]), [True]), ValueError, "truth, detectable: need truth (T, 3) and detectable (T,)"),
    ((np.array([[1.0, np.nan, 50.0], [2.0, 50.0, 50.0]]), [False, True]), ValueError,
     "truth: each row must be a finite position or all NaN"),
    ((np.array([[np.inf, 50.0, 50.0]]), [False]), ValueError, "truth: each row must be a finite position or all NaN"),
])
def test_clairvoyant_ceiling_refuses_what_is_not_a_truth(args, error, words):
    _raises(error, words, clairvoyant_ceiling, *args, [[0.0, 0, 0]], 5.0, LOW, HIGH)


@pytest.mark.parametrize("initial, step, low, high, words", [
    ([0.0, 0, 0, 1, 1, 1], 5.0, LOW, HIGH, "initial: expected an array of 3 entries"),  # read as two agents before
    ([[np.nan, 0, 0]], 5.0, LOW, HIGH, "initial: must be finite"),
    ([[0.0, 0, 0]], np.nan, LOW, HIGH, "max_step: must be a finite number in [0, inf)"),
    ([[0.0, 0, 0]], 5.0, HIGH, LOW, "low, high: the area's low corner must lie below its high one"),
    ([[0.0, 0, 0]], 5.0, LOW, [1.0, 1.0], "high: expected a vector of 3 entries"),
])
def test_the_chase_refuses_bad_agents_steps_and_areas(initial, step, low, high, words):
    _raises(ValueError, words, chase, _line([1.0]), initial, step, low, high)
    _raises(ValueError, words, clairvoyant_ceiling, _line([1.0]), [True], initial, step, low, high)


def test_the_chase_refuses_a_truth_of_states():
    _raises(ValueError, "truth: need truth (T, 3)", chase, np.ones((3, 6)), [[0.0, 0, 0]], 5.0, LOW, HIGH)


def test_the_ceiling_takes_what_it_took_before_the_checks():
    """0 / 1 for detectable, one agent as a vector, 0-d numbers, scalar corners, no steps."""
    truth = _line([10.0, 12.0, 14.0])
    plain = clairvoyant_ceiling(truth, [True, False, True], [[0.0, 50.0, 50.0]], 5.0, LOW, HIGH)
    loose = clairvoyant_ceiling(truth, [1, 0, 1], [0.0, 50.0, 50.0], np.array(5.0), 0.0, 100.0, d=np.array(8.0))
    assert loose.share == plain.share
    np.testing.assert_array_equal(loose.positions, plain.positions)
    assert clairvoyant_ceiling(np.zeros((0, 3)), [], [[0.0, 0, 0]], 5.0, LOW, HIGH).share is None


def test_an_absent_target_row_of_nan_is_still_taken():
    truth = np.array([[np.nan] * 3, [10.0, 50.0, 50.0]])
    c = clairvoyant_ceiling(truth, [False, True], [[0.0, 50.0, 50.0]], 5.0, LOW, HIGH, d=6.0)
    assert c.share == 1.0 and np.isnan(c.nearest[0])


def test_levels_still_broadcast_against_one_geometry():
    both = detection_probability(X, U, X, [0.2, 1.12], ANT)
    assert both.shape == (2,)
    assert both.tolist() == [float(detection_probability(X, U, X, lv, ANT)) for lv in (0.2, 1.12)]


def test_two_estimates_of_one_covariance_fuse_to_their_midpoint_in_either_order():
    C = np.diag([1.0, 2, 3, 4, 5, 6])
    a, b = Estimate(0.9, np.zeros(6), C), Estimate(0.8, np.full(6, 2.0), C)
    ab, ba = fuse([a, b]), fuse([b, a])
    np.testing.assert_allclose(ab.mean, np.ones(6))
    np.testing.assert_allclose(ba.mean, ab.mean)
    np.testing.assert_allclose(ab.cov, C)
    assert ab.weights.tolist() == [0.5, 0.5]


def test_a_ragged_corner_and_a_complex_number_in_a_list_are_named():
    _raises(TypeError, "low: expected numbers in a regular array", chase, _line([1.0]), [[0.0, 0, 0]], 1.0,
            [[0, 0], [0]], 100.0)
    _raises(TypeError, "aim: expected numbers", detection_probability, X, U,
            np.array([1.0, np.complex64(2 + 1j), 3.0], dtype=object), 1.12, ANT)
