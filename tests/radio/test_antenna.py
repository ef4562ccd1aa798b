"""The conic antenna: membership, detection probability (Eq. 9), received power (Eq. 10)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.config import load_scenario
from trackjam.simulation.build import antenna_model
from trackjam.radio.antenna import (
    cone_gain,
    detection_probability,
    inside_cone,
    interference_matrix,
    kernel_cone_gain,
    path_gain,
    received_power,
)

ANT = antenna_model(load_scenario("paper-fig3"))  # h_a 40 m, theta_a 80 deg
APEX = np.zeros(3)
UP = np.array([0.0, 0.0, 1.0])  # aim point straight above: axis +z
TAN40 = np.tan(np.deg2rad(40))


@pytest.mark.parametrize(
    "p, inside",
    [
        ((0, 0, 0), True),  # the apex
        ((0, 0, 20), True),  # on the axis
        ((0, 0, 40), True),  # centre of the base, s = h_a
        ((20 * TAN40, 0, 20), True),  # on the rim at mid height
        ((20 * TAN40 + 0.01, 0, 20), False),  # just outside the rim
        ((0, 0, 40.01), False),  # beyond h_a along the axis
        ((0, 0, -1), False),  # behind the apex
        ((40 * TAN40, 0, 40), True),  # rim of the base
        ((40 * TAN40, 0, 40.5), False),  # beyond the base
    ],
)
def test_cone_membership_on_hand_worked_points(p, inside):
    assert bool(inside_cone(np.array(p, float), APEX, UP, ANT.height, ANT.half_angle)) is inside


def test_height_is_measured_along_the_axis_whatever_the_direction():
    aim = np.array([1.0, 1.0, 1.0])
    axis = aim / np.linalg.norm(aim)
    assert inside_cone(39.9 * axis, APEX, aim, ANT.height, ANT.half_angle)
    assert not inside_cone(40.1 * axis, APEX, aim, ANT.height, ANT.half_angle)


def test_p_d_is_continuous_at_r0_and_follows_the_path_loss_beyond():
    r0 = ANT.r0
    below = detection_probability([0, 0, r0 - 1e-9], APEX, UP, ANT.l_max, ANT)
    above = detection_probability([0, 0, r0 + 1e-9], APEX, UP, ANT.l_max, ANT)
    assert below == pytest.approx(ANT.p_d_max) and above == pytest.approx(ANT.p_d_max, rel=1e-6)
    far = detection_probability([0, 0, 2 * r0], APEX, UP, ANT.l_max, ANT)
    assert far == pytest.approx(ANT.p_d_max * 0.5**ANT.n_e)


def test_p_d_is_zero_outside_the_cone_and_when_off():
    assert detection_probability([30, 0, 1], APEX, UP, ANT.l_max, ANT) == 0.0
    assert detection_probability([0, 0, -3], APEX, UP, ANT.l_max, ANT) == 0.0
    assert detection_probability([0, 0, 3], APEX, UP, 0.0, ANT) == 0.0


def test_p_d_scales_with_the_level_ratio_in_watts():
    p = np.array([0, 0, 12.0])
    for lw in ANT.levels_w:
        expected = lw / ANT.l_max * ANT.p_d_max * (ANT.r0 / 12.0) ** 2
        assert detection_probability(p, APEX, UP, lw, ANT) == pytest.approx(expected)


def test_received_power_scales_with_the_level():
    p = np.array([1.0, 2.0, 15.0])
    base = received_power(p, APEX, UP, 1.0, ANT)
    assert base == pytest.approx((6 / np.linalg.norm(p)) ** 2)
    for lw in ANT.levels_w:
        assert received_power(p, APEX, UP, lw, ANT) == pytest.approx(lw * base)


def test_interference_matrix_is_the_received_power_of_each_sender_at_each_receiver():
    u = np.array([[10, 10, 10], [10, 10, 20], [10, 10, 35], [80, 80, 80]], float)
    aims = np.array([[10, 10, 50]] * 4, float)
    lv = ANT.levels_w[[3, 2, 1, 3]]
    R = interference_matrix(u, aims, lv, ANT)
    assert np.all(np.diag(R) == 0)
    for i in range(4):
        for j in range(4):
            if i != j:
                assert R[i, j] == pytest.approx(received_power(u[i], u[j], aims[j], lv[j], ANT))
    assert R[1, 0] > 0 and R[0, 1] == 0  # agent 0 points up at agent 1, not the reverse
    assert R[3].sum() == 0


def test_path_gain_is_one_within_r0():
    assert np.all(path_gain(np.linspace(0, 6, 7), 6.0, 2.0) == 1.0)


@settings(max_examples=200, deadline=None)
@given(
    p=st.tuples(*[st.floats(-60, 60)] * 3),
    u=st.tuples(*[st.floats(-10, 10)] * 3),
    a=st.tuples(*[st.floats(-60, 60)] * 3),
)
def test_compiled_kernel_matches_numpy(p, u, a):
    p, u, a = (np.array(v, float) for v in (p, u, a))
    ref = cone_gain(p, u, a, ANT)
    d = a - u
    n = np.linalg.norm(d)
    ax = d / n if n > 1e-12 else np.array([0, 0, 1.0])
    got = kernel_cone_gain(*p, *u, *ax, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e)
    assert got == pytest.approx(float(ref), abs=1e-12)


def test_the_cones_farthest_point_and_so_the_clutters_range_is_the_rim_by_hand():
    """h_a / cos(theta_a / 2) from the configuration's own numbers (40 m, 80 deg: 52.2 m), not from
    the model's half angle: the clutter density and every update take max_range from here."""
    import math

    s = load_scenario("paper-fig3")
    expected = s.antenna.height / math.cos(math.radians(s.antenna.opening_angle_deg) / 2)
    assert ANT.max_range == pytest.approx(expected, rel=1e-12) and expected == pytest.approx(52.2163, abs=1e-4)
    # a point on the rim is in the cone and at that distance; one a little further along the rim's line is not
    from trackjam.radio.antenna import inside_cone

    rim = np.array([math.sin(ANT.half_angle), 0.0, math.cos(ANT.half_angle)]) * ANT.max_range * (1 - 1e-9)
    assert inside_cone(rim, np.zeros(3), np.array([0.0, 0.0, 1.0]), ANT.height, ANT.half_angle)
    assert not inside_cone(rim * 1.001, np.zeros(3), np.array([0.0, 0.0, 1.0]), ANT.height, ANT.half_angle)


@pytest.mark.parametrize("rel", [-1e-2, -5e-3, -1e-6, 1e-6, 5e-3, 1e-2])
def test_compiled_kernel_matches_numpy_across_the_cones_side(rel):
    """The random comparison above almost never lands near the cone's side, so a kernel with a
    cone 1 % wider passed it. Here, along random axes, points at (1 + rel) times the side's
    radius s tan(theta_a / 2), for s from near the apex to s = h_a: inside (gain > 0) below the
    side and outside (gain 0) above it, in both versions alike."""
    rng = np.random.default_rng(int(abs(rel) * 1e6) + (rel > 0))
    for s in np.r_[ANT.r0 * np.cos(ANT.half_angle), rng.uniform(1.0, ANT.height, 20), ANT.height]:
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        side = np.cross(axis, rng.normal(size=3))
        side /= np.linalg.norm(side)
        u = rng.uniform(-10, 10, 3)
        p = u + s * axis + (1 + rel) * s * ANT.tan_half * side
        ref = float(cone_gain(p, u, u + 10 * axis, ANT))
        got = kernel_cone_gain(*p, *u, *axis, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e)
        assert got == pytest.approx(ref, abs=1e-12)
        assert (got > 0) == (rel < 0)


@pytest.mark.parametrize("rel", [-1e-6, 1e-6])
def test_compiled_kernel_matches_numpy_at_the_base_and_at_r0(rel):
    """Just inside and just outside the base (s = h_a, on the axis and at half the base's
    radius), and on either side of eta = R_0 where g(eta) leaves 1."""
    rng = np.random.default_rng(7)
    for _ in range(10):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        side = np.cross(axis, rng.normal(size=3))
        side /= np.linalg.norm(side)
        u = rng.uniform(-10, 10, 3)
        base = [u + (1 + rel) * ANT.height * axis,
                u + (1 + rel) * ANT.height * axis + 0.5 * ANT.height * ANT.tan_half * side]
        at_r0 = [u + (1 + rel) * ANT.r0 * axis, u + (1 + rel) * ANT.r0 * (0.8 * axis + 0.6 * side)]
        for p in base + at_r0:
            ref = float(cone_gain(p, u, u + 10 * axis, ANT))
            got = kernel_cone_gain(*p, *u, *axis, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e)
            assert got == pytest.approx(ref, abs=1e-12)
        for p in base:
            assert (kernel_cone_gain(*p, *u, *axis, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e) > 0) == (rel < 0)
        for p in at_r0:  # 0.6 / 0.8 = tan(36.9 deg) < tan(40 deg): both inside the cone
            g = kernel_cone_gain(*p, *u, *axis, ANT.height, ANT.tan_half, ANT.r0, ANT.n_e)
            assert (g == 1.0) if rel < 0 else (0 < g < 1.0)
