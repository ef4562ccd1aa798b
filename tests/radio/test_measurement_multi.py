"""A scan with several targets: one target draws exactly what `sample_scan` draws; each target is
detected on its own with its own p_D; the draws do not depend on the outcome."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.radio.measurement import h, sample_scan, sample_scan_multi, target_exposure

NOISE = (0.8, np.pi / 50, np.pi / 50)
U = np.array([30.0, 30.0, 30.0])


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    x=st.one_of(st.none(), st.tuples(*[st.floats(0, 100)] * 3)),
    p_d=st.sampled_from([0.0, 0.3, 0.95, 1.0]),
    rate=st.sampled_from([0.0, 3.0, 20.0]),
)
def test_one_target_draws_exactly_what_sample_scan_draws(seed, x, p_d, rate):
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    Z1, from_target = sample_scan(a, None if x is None else np.array(x), U, p_d, NOISE, rate, 52.2)
    Zk, source = sample_scan_multi(b, [None if x is None else np.array(x)], U, np.array([p_d]), NOISE, rate, 52.2)
    assert np.array_equal(Z1, Zk) and Z1.dtype == Zk.dtype and Z1.shape == Zk.shape
    assert np.array_equal(from_target, source == 0) and set(source) <= {0, -1}
    assert a.uniform() == b.uniform()  # and leaves the stream where sample_scan leaves it


def test_one_target_as_an_array_row_or_a_nan_row_is_the_same_scan():
    x = np.array([[40.0, 35.0, 20.0]])
    for seed in range(20):
        Z1, s1 = sample_scan_multi(np.random.default_rng(seed), x, U, 0.7, NOISE, 3.0, 52.2)
        Z2, s2 = sample_scan_multi(np.random.default_rng(seed), [x[0]], U, [0.7], NOISE, 3.0, 52.2)
        Zn, sn = sample_scan_multi(np.random.default_rng(seed), np.full((1, 3), np.nan), U, 0.7, NOISE, 3.0, 52.2)
        Z0, s0 = sample_scan(np.random.default_rng(seed), None, U, 0.7, NOISE, 3.0, 52.2)
        assert np.array_equal(Z1, Z2) and np.array_equal(s1, s2)
        assert np.array_equal(Zn, Z0) and not (sn >= 0).any()


def test_every_sure_target_gives_one_measurement_in_target_order_then_clutter():
    X = np.array([[40.0, 30.0, 30.0], [np.nan] * 3, [30.0, 10.0, 50.0], [10.0, 10.0, 10.0]])
    p_d = np.array([1.0, 1.0, 1.0, 0.0])
    tiny = (1e-3, 1e-6, 1e-6)
    Z, source = sample_scan_multi(np.random.default_rng(4), X, U, p_d, tiny, 5.0, 52.2)
    assert list(source[:2]) == [0, 2] and (source[2:] == -1).all()
    assert np.allclose(Z[:2], h(X[[0, 2]], U), atol=1e-2)
    assert len(Z) == len(source)


def test_the_draws_do_not_depend_on_who_is_seen():
    X = np.array([[40.0, 30.0, 30.0], [30.0, 10.0, 50.0]])
    after = []
    for rows, p_d in [(X, [1.0, 1.0]), (X, [0.0, 0.0]), ([None, None], [1.0, 0.5]), ([X[0], None], [0.2, 1.0])]:
        rng = np.random.default_rng(11)
        sample_scan_multi(rng, rows, U, p_d, NOISE, 3.0, 52.2)
        after.append(rng.uniform())
    assert len(set(after)) == 1


def test_each_target_is_detected_on_its_own_at_its_rate():
    X = np.array([[40.0, 30.0, 30.0], [30.0, 10.0, 50.0], [20.0, 20.0, 20.0]])
    p_d = np.array([0.2, 0.5, 0.9])
    rng = np.random.default_rng(2)
    n = 4000
    seen = np.zeros((n, 3), dtype=bool)
    for i in range(n):
        _, source = sample_scan_multi(rng, X, U, p_d, NOISE, 0.0, 52.2)
        seen[i, source] = True
    rate = seen.mean(axis=0)
    assert np.all(np.abs(rate - p_d) < 4 * np.sqrt(p_d * (1 - p_d) / n))
    both = (seen[:, 0] & seen[:, 2]).mean()  # independent: P(0 and 2) = p_0 p_2
    assert abs(both - 0.18) < 4 * np.sqrt(0.18 * 0.82 / n)


def test_clutter_is_labelled_minus_one_and_counted_poisson():
    counts = [len(sample_scan_multi(np.random.default_rng(s), [None], U, 0.0, NOISE, 6.0, 52.2)[1]) for s in range(3000)]
    assert np.mean(counts) == pytest.approx(6.0, abs=4 * np.sqrt(6.0 / 3000))


def _antenna():
    from trackjam.config import load_scenario
    from trackjam.simulation.build import antenna_model

    return antenna_model(load_scenario("paper-fig3"))


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(1, 4), n=st.integers(1, 5))
def test_each_targets_exposure_is_what_the_one_target_engine_computes(seed, k, n):
    from trackjam.radio.antenna import detection_probability, received_power

    ant = _antenna()
    rng = np.random.default_rng(seed)
    X = rng.uniform(0, 100, size=(k, 3))
    exists, detectable = rng.uniform(size=k) < 0.8, rng.uniform(size=k) < 0.7
    X[~exists] = np.nan
    u = rng.uniform(0, 100, size=(n, 3))
    aim = np.where(rng.uniform(size=(n, 1)) < 0.5, X[rng.integers(k)], rng.uniform(0, 100, size=(n, 3)))
    aim = np.where(np.isfinite(aim), aim, u + 1.0)
    level_w = ant.levels_w[rng.integers(len(ant.levels_w), size=n)]
    to_target, p_d = target_exposure(X, exists, detectable, u, aim, level_w, ant)
    assert to_target.shape == p_d.shape == (n, k)
    for i in range(k):  # the engine's single-target lines, target by target
        want_w = received_power(X[i], u, aim, level_w, ant) if exists[i] else np.zeros(n)
        want_p = detection_probability(X[i], u, aim, level_w, ant) if exists[i] and detectable[i] else np.zeros(n)
        assert np.array_equal(to_target[:, i], want_w) and np.array_equal(p_d[:, i], want_p)


def test_an_agent_aimed_at_a_target_within_r0_detects_it_at_p_d_max():
    ant = _antenna()
    X = np.array([[50.0, 50.0, 50.0], [10.0, 10.0, 10.0]])
    u = np.array([[52.0, 50.0, 50.0]])
    to_target, p_d = target_exposure(X, [True, True], [True, True], u, X[:1], ant.levels_w[-1:], ant)
    assert p_d[0, 0] == pytest.approx(ant.p_d_max) and to_target[0, 0] == pytest.approx(ant.l_max)
    assert p_d[0, 1] == 0.0 and to_target[0, 1] == 0.0  # the other target is outside the cone


@pytest.mark.parametrize(
    "change, words",
    [
        ({"X": 5}, r"^X: expected a list of rows"),
        ({"X": np.zeros(3)}, r"^X: expected rows of 3 or 6 entries \(one per target\), got shape \(3,\)"),
        ({"X": [[1.0, 2.0]]}, r"^X\[0\]: expected 3 or 6 entries"),
        ({"X": [None, [1.0, np.nan, 2.0]]}, r"^X\[1\]: a position must be finite, or all NaN"),
        ({"X": [[1.0, np.inf, 2.0]]}, r"^X\[0\]: a position must be finite"),
        ({"X": [["a", "b", "c"]]}, r"^X\[0\]: expected numbers"),
        ({"p_d": [0.5, 0.5, 0.5]}, r"^p_d: expected one probability or one per row of X \(2\)"),
        ({"p_d": 1.5}, r"^p_d: must be finite numbers in \[0, 1\]"),
        ({"p_d": [0.5, np.nan]}, r"^p_d: must be finite numbers in \[0, 1\]"),
        ({"u": [1.0, 2.0]}, r"^u: expected a vector of 3 entries"),
        ({"noise_std": [0.0, 1.0, 1.0]}, r"^noise_std: expected one deviation > 0"),
        ({"clutter_rate": 1e12}, r"^clutter_rate: must be a finite number in \[0, 1000\]"),
        ({"max_range": -1.0}, r"^max_range: must be a finite number in \(0, inf\)"),
        ({"rng": 3}, r"^rng: expected a numpy Generator"),
    ],
)
def test_bad_arguments_are_refused_before_any_draw(change, words):
    # it had broadcast p_d, taken a partly NaN row as absent and drawn 1e12 clutter points
    rng = np.random.default_rng(5)
    args = {"rng": rng, "X": [[40.0, 30.0, 30.0], None], "u": U, "p_d": [0.5, 0.9], "noise_std": NOISE,
            "clutter_rate": 3.0, "max_range": 52.2} | change
    with pytest.raises((ValueError, TypeError), match=words):
        sample_scan_multi(**args)
    assert rng.uniform() == np.random.default_rng(5).uniform()  # nothing drawn


def test_the_meaningful_forms_of_the_arguments_are_taken():
    for X in ([[40.0, 30.0, 30.0, 1.0, 0.0, 0.0], None], np.array([[40.0, 30.0, 30.0], [np.nan] * 3]), [], ()):
        Z, source = sample_scan_multi(np.random.default_rng(1), X, U, 0.9, 0.5, 3.0, 52.2)
        assert Z.shape == (len(source), 3)
