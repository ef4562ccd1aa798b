"""The measurement model (Eqs. 6-8): h, its inverse, the noise and Poisson clutter."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.radio.measurement import (
    clutter_bounds,
    clutter_density,
    h,
    h_inverse,
    sample_clutter,
    sample_scan,
    wrap_angle,
)


@settings(max_examples=200, deadline=None)
@given(
    x=st.tuples(*[st.floats(-100, 100)] * 3),
    u=st.tuples(*[st.floats(-100, 100)] * 3),
)
def test_h_round_trips_with_its_inverse(x, u):
    x, u = np.array(x), np.array(u)
    if np.linalg.norm(x - u) < 1e-6:
        return
    assert np.allclose(h_inverse(h(x, u), u), x, atol=1e-7)


def test_h_on_hand_worked_points():
    u = np.array([1.0, 2.0, 3.0])
    assert np.allclose(h([1, 2, 8], u), [5, 0, 0])  # straight up: inclination 0
    assert np.allclose(h([1, 2, -2], u), [5, 0, np.pi])  # straight down
    assert np.allclose(h([1, 5, 3], u), [3, np.pi / 2, np.pi / 2])
    assert np.allclose(h([-3, 2, 3], u), [4, np.pi, np.pi / 2])  # azimuth pi, not -pi


def test_wrap_angle_lands_in_minus_pi_pi():
    a = np.array([-np.pi, np.pi, 3 * np.pi, -3 * np.pi / 2, 0.1])
    w = wrap_angle(a)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    assert np.allclose(np.cos(w), np.cos(a)) and np.allclose(np.sin(w), np.sin(a))


def test_mean_clutter_count_matches_lambda_c():
    rng = np.random.default_rng(7)
    counts = [len(sample_clutter(rng, 3.0, 52.2)) for _ in range(20000)]
    # Poisson: mean 3, standard error sqrt(3/20000) = 0.012
    assert np.mean(counts) == pytest.approx(3.0, abs=0.05)
    assert np.var(counts) == pytest.approx(3.0, abs=0.15)


def test_clutter_is_uniform_over_the_measurement_space():
    rng = np.random.default_rng(8)
    pts = np.vstack([sample_clutter(rng, 50.0, 52.2) for _ in range(200)])
    b = clutter_bounds(52.2)
    assert np.all(pts >= b[:, 0]) and np.all(pts <= b[:, 1])
    assert np.allclose(pts.mean(axis=0), b.mean(axis=1), atol=[1.0, 0.1, 0.05])
    assert clutter_density(52.2) == pytest.approx(1 / (52.2 * 2 * np.pi**2))


def test_scan_noise_has_the_configured_standard_deviations():
    rng = np.random.default_rng(9)
    x, u = np.array([10.0, 12.0, 20.0]), np.array([0.0, 0.0, 0.0])
    std = np.array([0.8, np.pi / 50, np.pi / 50])
    Z = np.array([sample_scan(rng, x, u, 1.0, std, 0.0, 50.0)[0][0] for _ in range(5000)])
    err = Z - h(x, u)
    err[:, 1] = wrap_angle(err[:, 1])
    assert np.allclose(err.std(axis=0), std, rtol=0.05)
    assert np.allclose(err.mean(axis=0), 0, atol=3 * std / np.sqrt(5000) + 1e-3)


def test_no_target_measurement_when_absent_or_undetected():
    rng = np.random.default_rng(1)
    for _ in range(100):
        _, from_target = sample_scan(rng, None, np.zeros(3), 1.0, [0.8, 0.06, 0.06], 3.0, 50.0)
        assert not from_target.any()
        _, from_target = sample_scan(rng, np.ones(3) * 5, np.zeros(3), 0.0, [0.8, 0.06, 0.06], 3.0, 50.0)
        assert not from_target.any()


def test_detection_frequency_matches_p_d():
    rng = np.random.default_rng(2)
    hits = sum(sample_scan(rng, np.ones(3) * 5, np.zeros(3), 0.3, [0.8, 0.06, 0.06], 0.0, 50.0)[1].any() for _ in range(10000))
    assert hits / 10000 == pytest.approx(0.3, abs=0.02)
