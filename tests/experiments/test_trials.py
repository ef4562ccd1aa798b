"""Section VI's trial draw: target uniform in the area, pursuers uniform in a 20 m ball around
it (and inside the area), antennas aimed at the ball's centre; seeds from (seed, config, k)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from trackjam.experiments.trials import (
    BALL_RADIUS_M,
    draw_rng,
    draw_trial,
    simulation_seed,
    uniform_in_ball,
)

LOW, HIGH = (0.0, 0.0, 0.0), (100.0, 100.0, 100.0)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32), k=st.integers(0, 500))
def test_pursuers_lie_in_the_ball_and_the_area_and_aim_at_the_target(seed, k):
    d = draw_trial(seed, k, LOW, HIGH, 3, birth_speed=3.0)
    x = d.x0[:3]
    assert np.all(x >= 0) and np.all(x <= 100)
    assert np.all(np.abs(d.x0[3:]) <= 3.0)
    assert d.u0.shape == (3, 3)
    assert np.all(np.linalg.norm(d.u0 - x, axis=1) <= BALL_RADIUS_M)
    assert np.all(d.u0 >= 0) and np.all(d.u0 <= 100)
    np.testing.assert_array_equal(d.aim, x)


def test_a_trial_is_a_function_of_seed_and_index_only():
    a = draw_trial(3, 5, LOW, HIGH, 3, 3.0)
    b = draw_trial(3, 5, LOW, HIGH, 3, 3.0)
    np.testing.assert_array_equal(a.x0, b.x0)
    np.testing.assert_array_equal(a.u0, b.u0)
    c = draw_trial(3, 6, LOW, HIGH, 3, 3.0)
    assert not np.array_equal(a.x0, c.x0)


def test_simulation_seeds_differ_by_configuration_and_trial_and_are_reproducible():
    seeds = {simulation_seed(0, c, k) for c in range(1, 9) for k in range(20)}
    assert len(seeds) == 160
    assert simulation_seed(0, 2, 3) in seeds and simulation_seed(1, 2, 3) not in seeds  # the experiment's seed counts
    assert all(0 <= s < 2**63 for s in seeds)


def test_target_position_is_uniform_in_the_area():
    x = np.array([draw_trial(11, k, LOW, HIGH, 1, 3.0).x0[:3] for k in range(400)])
    for axis in range(3):
        assert stats.kstest(x[:, axis] / 100.0, "uniform").pvalue > 1e-3


def test_points_are_uniform_in_the_ball():
    # uniform in a ball of radius R: (r / R)^3 is uniform on [0, 1], directions isotropic
    rng = draw_rng(0, 0)
    p = np.array([uniform_in_ball(rng, np.zeros(3), 20.0) for _ in range(2000)])
    r = np.linalg.norm(p, axis=1)
    assert stats.kstest((r / 20.0) ** 3, "uniform").pvalue > 1e-3
    assert stats.kstest((p[:, 2] / r + 1) / 2, "uniform").pvalue > 1e-3  # cos(inclination)


def test_a_target_in_a_corner_still_gets_its_pursuers_inside_the_area():
    # a tiny area forces the rejection loop to work: the ball sticks out on every side
    d = draw_trial(1, 0, (0, 0, 0), (5, 5, 5), 3, 1.0)
    assert np.all(d.u0 >= 0) and np.all(d.u0 <= 5)
