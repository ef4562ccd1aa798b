"""Birth densities and their importance proposals: the two-scan proposal draws the same density
as moving the uniform birth blindly, with far more particles where the second scan says the
target is; measurement-driven birth covers fast targets."""

import math

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.estimation.bernoulli import Scan
from trackjam.estimation.birth import (
    YOUNG_FLOOR,
    YOUNG_INFLATE,
    Gaussians,
    UniformBirth,
    draw_measurement_birth,
    draw_uniform_birth,
    redraw_young,
)
from trackjam.estimation.kernels import kernel_cv_predict
from trackjam.radio.measurement import clutter_density, h
from trackjam.simulation.build import antenna_model, make_filter

# a small box and coarse angles, so that brute force on b itself is accurate
S = load_scenario("paper-fig3", ["sensor.noise_std=[0.6, 0.12, 0.12]"])
ANT = antenna_model(S)
SIGMA = np.asarray(S.sensor.noise_std)
LOG_LC = math.log(S.sensor.clutter_rate * clutter_density(ANT.max_range))
B = UniformBirth(np.zeros(3), np.full(3, 12.0), 3.0)
U = np.array([1.0, 1.0, 1.0])
X_PREV = np.array([5.0, 6.0, 5.5])  # the target at t-1, then moving at (1.8, -1.5, 0.6) m/s
X_NOW = X_PREV + [1.8, -1.5, 0.6]
CLUTTER = np.array([[9.0, 0.3, 0.7]])
SCAN_PREV = Scan.of(np.vstack([h(X_PREV, U)[None], CLUTTER]), U, X_PREV, ANT.l_max, ANT)
SCAN_NOW = Scan.of(h(X_NOW, U)[None], U, X_NOW, ANT.l_max, ANT)
ACCEL_VAR = 0.5


def log_L(scan, X):
    return scan.log_factors(X, ANT, SIGMA, LOG_LC)


def moved(rng, X):
    X = X.copy()
    kernel_cv_predict(X, rng.standard_normal((len(X), 3)), 1.0, math.sqrt(ACCEL_VAR))
    return X


def young_factor(X_now, log_w):
    """sum_i w_i L_t(x_i): the young component's share of 1 - q_t, per unit of its mass."""
    return float(np.exp(log_w + log_L(SCAN_NOW, X_now)).sum())


def brute_force_young_factor(rng, k=4_000_000):
    """Plain draws of b, weighted by L_{t-1}, moved by Eq. (1), then averaged L_t."""
    X = B.draw(rng, k)
    w = np.exp(log_L(SCAN_PREV, X))
    return float(w @ np.exp(log_L(SCAN_NOW, moved(rng, X))) / w.sum())


def two_scan(rng, k=2000):
    G_prev = Gaussians.of_scan(SCAN_PREV.Z, U, SIGMA, YOUNG_INFLATE, YOUNG_FLOOR)
    G_now = Gaussians.of_scan(SCAN_NOW.Z, U, SIGMA, YOUNG_INFLATE, YOUNG_FLOOR)
    X0, log_w = redraw_young(rng, B, G_prev, G_now, k, 0.5, ACCEL_VAR, lambda X: log_L(SCAN_PREV, X))
    return moved(rng, X0), log_w


def blind(rng, k=2000):
    """Today's path without the redraw: the importance-sampled birth of t-1, updated, moved."""
    X0, log_w = draw_uniform_birth(rng, B, Gaussians.of_scan(SCAN_PREV.Z, U, SIGMA), k, 0.5)
    log_w = log_w + log_L(SCAN_PREV, X0)
    return moved(rng, X0), log_w - np.logaddexp.reduce(log_w)


def test_two_scan_proposal_keeps_the_young_density_and_cuts_its_monte_carlo_error():
    exact = brute_force_young_factor(np.random.default_rng(0))
    rng = np.random.default_rng(1)
    redrawn = np.array([young_factor(*two_scan(rng)) for _ in range(30)])
    plain = np.array([young_factor(*blind(rng)) for _ in range(30)])
    print(f"brute force {exact:.4g}, two-scan {redrawn.mean():.4g} ± {redrawn.std():.3g}, "
          f"blind {plain.mean():.4g} ± {plain.std():.3g}")
    assert exact > 1.0  # the second detection supports the young component
    assert abs(redrawn.mean() / exact - 1) < 0.04
    assert abs(plain.mean() / exact - 1) < 0.15
    assert redrawn.std() < 0.5 * plain.std()


def test_two_scan_weights_vanish_outside_the_birth_support():
    X0, log_w = redraw_young(
        np.random.default_rng(2), B, Gaussians.of_scan(SCAN_PREV.Z, U, SIGMA), Gaussians.of_scan(SCAN_NOW.Z, U, SIGMA),
        3000, 0.5, ACCEL_VAR, lambda X: log_L(SCAN_PREV, X),
    )
    outside = np.any(np.abs(X0[:, 3:]) > 3.0, axis=1) | ~B.in_area(X0[:, :3])
    assert outside.any() and np.all(log_w[outside] == -np.inf)
    assert np.exp(log_w).sum() == pytest.approx(1.0)


def test_measurement_birth_draws_velocity_within_its_own_speed():
    G = Gaussians.of_scan(h(X_PREV, U)[None], U, SIGMA, inflate=1.0)
    X, log_w = draw_measurement_birth(np.random.default_rng(3), B, G, 20_000, speed=7.0)
    assert np.abs(X[:, 3:]).max() <= 7.0 and np.abs(X[:, 3:]).max() > 6.9
    # position = a draw around the measurement moved one step by its velocity
    np.testing.assert_allclose((X[:, :3] - X[:, 3:]).mean(axis=0), G.mu[0], atol=0.05)
    np.testing.assert_allclose(np.exp(log_w), 1 / 20_000)


@pytest.mark.parametrize("birth, mix", [("uniform", 0.0), ("measurement", 1.0), ("mixed", 0.3)])
def test_birth_options_split_the_birth_particles_by_the_mixing_share(birth, mix):
    s = load_scenario("paper-fig3", filter__birth=birth, filter__birth_mix=0.3, filter__particles=500,
                      filter__birth_particles=200)
    f = make_filter(s, np.random.default_rng(4))
    assert f.n_mb == round(mix * 200)
    for _ in range(2):
        f.predict()
        est = f.update(np.array([h([30.0, 30.0, 30.0], U), [20.0, 1.0, 1.0]]), U, np.full(3, 30.0), ANT.l_max)
        assert 0.0 <= est.existence <= 1.0 and np.all(np.isfinite(est.mean))
    if birth == "measurement":
        assert f._young is None  # measurement-driven births are resampled with the survivors
    else:
        assert f._young is not None and len(f._young.X) == 200 - f.n_mb
