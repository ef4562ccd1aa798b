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
    wide = UniformBirth(np.full(3, -30.0), np.full(3, 40.0), 3.0)  # no particle near a wall
    X, log_w = draw_measurement_birth(np.random.default_rng(3), wide, G, 20_000, speed=7.0)
    assert np.abs(X[:, 3:]).max() <= 7.0 and np.abs(X[:, 3:]).max() > 6.9
    # position = a draw around the measurement moved one step by its velocity
    np.testing.assert_allclose((X[:, :3] - X[:, 3:]).mean(axis=0), G.mu[0], atol=0.05)
    np.testing.assert_allclose(np.exp(log_w), 1 / 20_000)


def test_measurement_birth_is_truncated_to_the_area():
    """A detection 1 m from a wall: the untruncated draw puts a third of the births beyond it. The
    births are the untruncated density restricted to the area (brute force: draw it and keep what
    is inside), and every one is inside."""
    near = np.array([1.0, 6.0, 5.5])
    G = Gaussians.of_scan(h(near, U)[None], U, SIGMA, inflate=1.0)
    X, log_w = draw_measurement_birth(np.random.default_rng(5), B, G, 40_000, speed=3.0)
    assert B.in_area(X[:, :3]).all()
    np.testing.assert_allclose(np.exp(log_w), 1 / 40_000)
    wide = UniformBirth(np.full(3, -30.0), np.full(3, 40.0), 3.0)
    Y, _ = draw_measurement_birth(np.random.default_rng(6), wide, G, 400_000, speed=3.0)
    inside = B.in_area(Y[:, :3])
    assert 0.25 < 1 - inside.mean() < 0.45  # what the old draw left outside
    ref = Y[inside]
    np.testing.assert_allclose(X.mean(axis=0), ref.mean(axis=0), atol=0.03)
    np.testing.assert_allclose(X.std(axis=0), ref.std(axis=0), rtol=0.02)


def test_measurement_birth_beyond_the_area_falls_back_to_the_uniform_birth():
    """A scan whose only point lies far outside the area (clutter reaches 52 m from an agent):
    no redraw lands inside, so the births are b's own, with the measurement birth's speed."""
    far = np.array([40.0, 6.0, 5.5])
    G = Gaussians.of_scan(h(far, U)[None], U, SIGMA, inflate=1.0)
    X, _ = draw_measurement_birth(np.random.default_rng(7), B, G, 5_000, speed=5.0)
    assert B.in_area(X[:, :3]).all()
    np.testing.assert_allclose(X[:, :3].mean(axis=0), (B.low + B.high) / 2, atol=0.3)  # uniform in the box
    assert np.abs(X[:, 3:]).max() <= 5.0 and np.abs(X[:, 3:]).max() > 4.9


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


def _shared_scans_existence(two_scan: bool, teammate_at_first: bool, seeds: range, team: bool = True) -> float:
    """Mean existence after two steps of agent A's filter, which also weighs teammate B's scans
    (``fusion.share: scans``): at step 1 A detects near p1 and B, 4.4 m from p1 with its cone on
    it, misses; at step 2 A detects again. The birth probability is raised to 0.5 so that the
    young component (born at step 1) weighs in the existence."""
    s = load_scenario("paper-fig3", ["filter.birth_prob=0.5", f"filter.team_proposals={str(team).lower()}"])
    ant = antenna_model(s)
    level = ant.l_max
    p1 = np.array([57.0, 55.0, 51.0])
    p2 = p1 + [1.5, -1.0, 0.5]
    ua, ub = np.array([50.0, 50.0, 50.0]), np.array([60.0, 52.0, 50.0])
    za1 = np.vstack([h(p1, ua) + [0.2, 0.01, -0.01], [20.0, 1.0, 1.0]])
    zb1 = np.array([[30.0, -2.0, 0.5]])  # clutter only: B misses the target
    za2 = np.vstack([h(p2, ua) + [-0.3, -0.01, 0.02], [35.0, -2.0, 2.5]])
    out = []
    for seed in seeds:
        f = make_filter(s, np.random.default_rng(seed), two_scan=two_scan)
        f.predict()
        f.update(za1, ua, p1, level, others=[Scan.of(zb1, ub, p1, level, ant)] if teammate_at_first else [])
        f.predict()
        out.append(f.update(za2, ua, p2, level).existence)
    return float(np.mean(out))


def test_the_redrawn_young_component_keeps_the_teammates_scans():
    """The two-scan proposal draws the young component again at step 2 from b times its scans'
    factors at step 1: all of them, the teammates' too. It had taken A's own scan only, so B's
    miss, which the filter without the redraw weighs (0.744), was lost (0.802, the same as with
    no scan from B)."""
    seeds = range(500, 510)
    reference = _shared_scans_existence(False, True, seeds)  # no redraw: the uniform births as weighed
    redrawn = _shared_scans_existence(True, True, seeds)
    without_b = _shared_scans_existence(True, False, seeds)
    assert abs(redrawn - reference) < 0.02
    assert without_b - redrawn > 0.03  # B's miss counts
    # filter.team_proposals: false, the earlier behaviour: the redraw forgets B's miss
    assert abs(_shared_scans_existence(True, True, seeds, team=False) - without_b) < 0.01


def test_a_teammates_detection_is_weighed_by_births_drawn_near_it():
    """With shared scans a teammate's detection weighs every particle, so the births must be
    proposed near it too: they had been drawn around the agent's own measurements only, and a
    lone teammate's detection (A sees clutter, B the target) left A's existence at 0.5013 where
    the exact update gives 0.5064 (brute force on the uniform birth, stratified near the target)."""
    from trackjam.estimation.kernels import kernel_update_factors
    from trackjam.radio.antenna import axis_of

    s = load_scenario("paper-fig3", ["filter.birth_prob=0.5", "antenna.height=40", "antenna.opening_angle_deg=80",
                                     "filter.team_proposals=true"])
    ant, sigma = antenna_model(s), np.asarray(s.sensor.noise_std)
    log_lc = math.log(s.sensor.clutter_rate * clutter_density(ant.max_range))
    level = ant.l_max
    ua, ub, aim_a, p1 = np.array([20.0, 20, 20]), np.array([50.0, 50, 50]), np.array([30.0, 80, 60]), np.array([57.0, 55, 51])
    za = np.array([[25.0, 1.2, 1.0]])  # clutter: A's cone points elsewhere
    zb = np.vstack([h(p1, ub) + [0.2, 0.01, -0.01], [20.0, 1.0, 1.0]])

    def factor(X, Z, u, aim):
        return np.exp(kernel_update_factors(np.ascontiguousarray(X), Z, u, axis_of(u, aim), level / ant.l_max * ant.p_d_max,
                                            ant.height, ant.tan_half, ant.r0, ant.n_e, sigma, log_lc)[1])

    # exact: e_pred = p_b = 0.5 of the uniform b; A = E_b[L_A L_B], stratified on a 10 m box around p1
    rng = np.random.default_rng(7)
    lo, hi, k = p1 - 5, p1 + 5, 1_000_000
    share = 1000.0 / 1e6
    near = np.column_stack([rng.uniform(lo, hi, (k, 3)), np.zeros((k, 3))])
    far = np.column_stack([rng.uniform(0, 100, (k, 3)), np.zeros((k, 3))])
    far = far[~np.all((far[:, :3] >= lo) & (far[:, :3] <= hi), axis=1)]
    both = lambda X: factor(X, za, ua, aim_a) * factor(X, zb, ub, p1)  # noqa: E731
    A = share * both(near).mean() + (1 - share) * both(far).mean()
    exact = 0.5 * A / (0.5 + 0.5 * A)

    seen = []
    for seed in range(400, 410):
        f = make_filter(s, np.random.default_rng(seed))
        f.predict()
        seen.append(f.update(za, ua, aim_a, level, others=[Scan.of(zb, ub, p1, level, ant)]).existence)
    assert exact > 0.505  # B's detection is evidence: the prior is 0.5
    assert abs(np.mean(seen) - exact) < 0.0025, (np.mean(seen), exact)  # the brute force alone is within about 0.001


def test_the_uniform_birth_is_zero_past_every_face_of_the_box():
    """b's support is the box: a point just past any face, low or high, is outside it, and the
    importance draw gives weight 0 to the proposal's particles that land there (here a scan
    Gaussian centred on the high corner, so about 7/8 of them do)."""
    inside = np.array([[0.0, 0.0, 0.0], [12.0, 12.0, 12.0], [6.0, 6.0, 6.0]])
    assert B.in_area(inside).all()
    for k in range(3):
        for value in (-0.01, 12.01):
            p = np.full((1, 3), 6.0)
            p[0, k] = value
            assert not B.in_area(p)[0], p
    corner = np.full(3, 12.0)
    G = Gaussians.of(corner[None], np.eye(3)[None])
    X, log_w = draw_uniform_birth(np.random.default_rng(5), B, G, 4000, 0.5)
    outside = ~np.all((X[:, :3] >= 0.0) & (X[:, :3] <= 12.0), axis=1)
    assert 0.3 < outside.mean() < 0.5  # half from G, 7/8 of those past the corner
    assert np.all(log_w[outside] == -np.inf) and np.all(np.isfinite(log_w[~outside]))
    assert np.exp(log_w).sum() == pytest.approx(1.0)


def mixed_filter(seed=0):
    s = load_scenario("paper-fig3", filter__birth="mixed", filter__birth_mix=0.3, filter__particles=500,
                      filter__birth_particles=400)
    f = make_filter(s, np.random.default_rng(seed))
    assert f.e == 0.0 and f.n_mb == 120
    return s, f


def test_a_mixed_birth_predicts_b_itself_from_nothing():
    """From existence 0 the prediction is all birth, e_{t|t-1} = p_b, and with no scan yet both
    parts of a mixed b_t are b itself: the predicted mean is the box's centre (the measurement-
    driven 30 % are 120 draws, so within 0.3 * 29 / sqrt(120) = 0.8 m per axis; 3 m is ~4 sd)
    and zero velocity, not the parts' weights summed past 1."""
    s, f = mixed_filter()
    est = f.predict()
    assert est.existence == pytest.approx(s.filter.birth_prob, abs=1e-15)
    centre = (np.asarray(s.area.low) + np.asarray(s.area.high)) / 2
    np.testing.assert_allclose(est.mean[:3], centre, atol=3.0)
    np.testing.assert_allclose(est.mean[3:], 0.0, atol=0.3 * s.filter.measurement_birth_speed)


@pytest.mark.parametrize("seed", range(3))
def test_a_mixed_birth_scan_that_cannot_detect_leaves_the_existence(seed):
    """A scan at 0 W detects nothing anywhere: L = 1 for every particle, so the update's
    evidence is the predicted weights' total, which is 1 only when the blocks' shares (the
    survivors', the measurement-driven births' p_b-share * mix and the uniform ones' * (1 - mix))
    add up to 1: e_t = e_{t|t-1}."""
    _, f = mixed_filter(seed)
    U0, aim = np.array([10.0, 10.0, 10.0]), np.array([14.0, 13.0, 12.0])
    for _ in range(3):
        e_pred = f.predict().existence
        est = f.update(np.empty((0, 3)), U0, aim, 0.0)
        assert est.existence == pytest.approx(e_pred, rel=1e-9)
