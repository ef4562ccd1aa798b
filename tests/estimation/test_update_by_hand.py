"""Section V-A's update pinned by numbers worked out by hand, with none of trackjam's own helpers
(h, p_D, the clutter density, the Gaussian) in the reference: only the paper's constants.

1. One particle on the antenna's axis 8 m away, one measurement exactly at its h(x): every
   factor of the bracket L = (1 - p_D) + p_D g / (lambda_c p_c) is a closed form
   (p_D = 0.95 (6/8)^2, g = 1 / ((2 pi)^1.5 sigma_rho sigma_az sigma_inc), p_c = 1 / (R 2 pi^2)
   with R = h_a / cos(theta_a / 2)), so e_t = L e / (1 - e + e L).
2. The whole filter (survivors, the young component, the uniform birth) with p_D the same
   constant at every particle: a miss then gives e_t = (1 - p) e / (1 - e p) whatever the
   particles, which holds only if the predicted density's parts (p_s e / e_pred for the
   survivors, split between the resampled part and the young component by its mass, and
   p_b (1 - e) / e_pred for the births) weigh 1 in all.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from trackjam.estimation.bernoulli import BernoulliFilter, FilterParams, bernoulli_update
from trackjam.radio.antenna import AntennaModel

SIGMA = (0.8, math.pi / 50, math.pi / 50)  # Sigma_w as standard deviations (docs/model.md)
PAPER = AntennaModel(height=40.0, half_angle=math.radians(40.0), r0=6.0, n_e=2.0, p_d_max=0.95,
                     levels_w=10 ** (np.array([-np.inf, -50.0, -7.0, 0.5]) / 10), delta_w=1e-4)


def hand_factor(level_w: float, inside: bool, detected: bool) -> float:
    """L of a particle 8 m along the axis (or outside the cone), by the paper's numbers."""
    p_d = (level_w / 10 ** 0.05) * 0.95 * (6.0 / 8.0) ** 2 if inside else 0.0
    if not detected:
        return 1.0 - p_d
    g = 1.0 / ((2 * math.pi) ** 1.5 * SIGMA[0] * SIGMA[1] * SIGMA[2])  # the measurement sits at h(x)
    rim = 40.0 / math.cos(math.radians(40.0))
    lambda_pc = 3.0 / (rim * 2 * math.pi * math.pi)
    return (1.0 - p_d) + p_d * g / lambda_pc


@pytest.mark.parametrize("level", [1, 2, 3])
@pytest.mark.parametrize("e_pred", [0.02, 0.3, 0.9])
def test_one_particle_on_the_axis_by_hand(level, e_pred):
    u = np.array([10.0, 20.0, 30.0])
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    x_in = np.r_[u + 8.0 * axis, 1.0, 0.0, 0.0]
    x_out = np.r_[u - 8.0 * axis, 0.0, 0.0, 0.0]  # behind the agent: outside the cone
    d = 8.0 * axis
    z = np.array([[8.0, math.atan2(d[1], d[0]), math.atan2(math.hypot(d[0], d[1]), d[2])]])
    level_w = float(PAPER.levels_w[level])
    log_lc = math.log(3.0 / (40.0 / math.cos(math.radians(40.0)) * 2 * math.pi ** 2))
    # the filter's own log(lambda_c p_c): clutter uniform over rho in [0, the rim], the azimuth's
    # 2 pi and the inclination's pi
    paper_filter = BernoulliFilter(replace(BOX, low=np.zeros(3), high=np.full(3, 100.0)), PAPER, np.random.default_rng(0))
    assert paper_filter.log_lambda_c == pytest.approx(log_lc, rel=1e-14)
    w = np.array([0.75, 0.25])
    for Z, detected in ((z, True), (np.zeros((0, 3)), False)):
        e, log_post, log_A, log_L = bernoulli_update(
            e_pred, np.array([x_in, x_out]), np.log(w), Z, u, u + 20 * axis, level_w, PAPER,
            np.array(SIGMA), log_lc)
        L = np.array([hand_factor(level_w, True, detected), hand_factor(level_w, False, detected)])
        A = float(w @ L)  # 1 - q_t
        np.testing.assert_allclose(np.exp(log_L), L, rtol=1e-12)
        assert math.exp(log_A) == pytest.approx(A, rel=1e-12)
        assert e == pytest.approx(A * e_pred / (1 - e_pred + e_pred * A), rel=1e-12)
        np.testing.assert_allclose(np.exp(log_post), w * L / A, rtol=1e-12)


# a cone that holds the whole box [0, 10]^3 (apex just outside a corner, axis to the centre,
# half angle 85 deg, so its side is 30 deg beyond the corners) with R_0 beyond the box's
# diagonal: p_D = (l / l_max) p_D^max at every particle
FLAT = AntennaModel(height=40.0, half_angle=math.radians(85.0), r0=100.0, n_e=2.0, p_d_max=0.95,
                    levels_w=np.array([0.0, 0.1, 1.0]), delta_w=1e-4)
BOX = FilterParams(birth_prob=0.02, survival_prob=0.98, particles=400, birth_particles=100, birth="uniform",
                   birth_mix=0.5, measurement_birth_speed=8.0, birth_speed=3.0, accel_var=0.5, walls="reflect",
                   low=np.zeros(3), high=np.full(3, 10.0), noise_std=np.array(SIGMA), clutter_rate=3.0)
U = np.full(3, -1e-3)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_miss_of_the_whole_filter_is_the_closed_form_when_p_d_is_flat(seed):
    rng = np.random.default_rng(seed)
    f = BernoulliFilter(BOX, FLAT, np.random.default_rng(seed), existence=0.7)
    e = 0.7
    misses = 0
    for t in range(10):
        e_pred = 0.02 * (1 - e) + 0.98 * e
        assert f.predict().existence == pytest.approx(e_pred, rel=1e-14)
        level = [2, 1, 2, 0, 2][t % 5]
        if t % 3 == 0:  # a detection somewhere in the box: births and a young component to weigh
            d = rng.uniform(0, 10, 3) - U
            Z = np.array([[np.linalg.norm(d), math.atan2(d[1], d[0]), math.atan2(math.hypot(d[0], d[1]), d[2])]])
            e = f.update(Z, U, np.full(3, 5.0), FLAT.levels_w[level]).existence
            continue
        p = 0.95 * FLAT.levels_w[level] / FLAT.l_max
        e = f.update(np.zeros((0, 3)), U, np.full(3, 5.0), FLAT.levels_w[level]).existence
        assert e == pytest.approx((1 - p) * e_pred / (1 - e_pred * p), rel=1e-12, abs=1e-15)
        misses += 1
    assert misses == 6


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_scan_at_level_off_leaves_the_whole_filters_existence_on_its_prediction(seed):
    """Every other scan holds a measurement taken at level off (p_D = 0, every L_i = 1), the
    others one at full power: the young component born at a detection is drawn again by the
    two-scan proposal (both its scans hold measurements), and e_t = e_{t|t-1} must still hold,
    which it does only if the redrawn component keeps its mass."""
    rng = np.random.default_rng(seed)
    f = BernoulliFilter(BOX, FLAT, np.random.default_rng(seed), existence=0.6)
    e = 0.6
    for t in range(10):
        e_pred = 0.02 * (1 - e) + 0.98 * e
        f.predict()
        d = rng.uniform(0, 10, 3) - U
        Z = np.array([[np.linalg.norm(d), math.atan2(d[1], d[0]), math.atan2(math.hypot(d[0], d[1]), d[2])]])
        off = t % 2 == 1
        young = f._young is not None
        e = f.update(Z, U, np.full(3, 5.0), 0.0 if off else FLAT.l_max).existence
        if off:
            assert young  # the component born at the detection before is weighed (and redrawn)
            assert e == pytest.approx(e_pred, rel=1e-12)
