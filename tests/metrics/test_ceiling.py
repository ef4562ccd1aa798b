"""The clairvoyant-chaser ceiling: agents that run straight at the true target."""

import json
import math

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.metrics.ceiling import NEAR, chase, clairvoyant_ceiling
from trackjam.radio.antenna import detection_probability
from trackjam.simulation.build import antenna_model

LOW, HIGH = (0.0, 0.0, 0.0), (100.0, 100.0, 100.0)


def line(xs):
    """A truth moving along the x axis at y = z = 50."""
    xs = np.asarray(xs, float)
    return np.stack([xs, np.full_like(xs, 50.0), np.full_like(xs, 50.0)], axis=1)


def reference_chase(truth, initial, max_step, low, high):
    """The chaser in scalar Python: one agent, one coordinate at a time."""
    out = []
    agents = [list(map(float, u)) for u in initial]
    for x in truth:
        if not any(math.isnan(v) for v in x):
            for u in agents:
                gap = [x[k] - u[k] for k in range(3)]
                dist = math.sqrt(sum(g * g for g in gap))
                move = 1.0 if dist <= max_step else max_step / dist
                for k in range(3):
                    u[k] = min(max(u[k] + move * gap[k], low[k]), high[k])
        out.append([list(u) for u in agents])
    return np.array(out)


def test_a_chaser_closes_on_a_still_target_a_step_at_a_time():
    D, v = 20.0, 5.0
    c = clairvoyant_ceiling(line([50.0] * 6), [True] * 6, [[50.0 - D, 50.0, 50.0]], v, LOW, HIGH, d=8.0)
    k = np.arange(1, 7)
    np.testing.assert_allclose(c.nearest, np.maximum(0.0, D - k * v), atol=1e-12)
    assert c.share == 4 / 6  # distances 15, 10, 5, 0, 0, 0


@pytest.mark.parametrize("w, expected", [(2.0, lambda k: np.maximum(0, 30 - 3 * k)), (7.0, lambda k: 30 + 2 * k)])
def test_a_chaser_gains_on_a_slower_target_and_falls_behind_a_faster_one(w, expected):
    T = 12
    k = np.arange(1, T + 1)
    truth = line(30.0 + w * k)
    c = clairvoyant_ceiling(truth, [True] * T, [[0.0, 50.0, 50.0]], 5.0, LOW, HIGH)
    np.testing.assert_allclose(c.nearest, expected(k), atol=1e-9)
    assert c.share == pytest.approx(np.mean(expected(k) <= NEAR))


def test_the_ceiling_counts_the_nearest_agent_at_detectable_steps_only():
    truth = line([50.0] * 4)
    truth[1] = np.nan  # absent: the chasers hover
    detectable = [True, False, False, True]  # step 2 occluded: they still chase
    initial = [[20.0, 50.0, 50.0], [50.0, 50.0, 10.0]]
    c = clairvoyant_ceiling(truth, detectable, initial, 5.0, LOW, HIGH, d=20.0)
    np.testing.assert_allclose(c.positions[:, 0, 0], [25.0, 25.0, 30.0, 35.0])
    np.testing.assert_allclose(c.positions[:, 1, 2], [15.0, 15.0, 20.0, 25.0])
    assert np.isnan(c.nearest[1])
    np.testing.assert_allclose(c.nearest[[0, 2, 3]], [25.0, 20.0, 15.0])
    assert c.share == 1 / 2  # 25 m then 15 m at the two detectable steps (20 m at step 2 is not one)
    assert json.loads(json.dumps(c.summary(), allow_nan=False)) == {
        "ceiling_share": 0.5, "ceiling_d_m": 20.0}


def test_a_target_never_detectable_has_no_ceiling():
    c = clairvoyant_ceiling(line([50.0, 51.0]), [False, False], [[0.0, 0.0, 0.0]], 5.0, LOW, HIGH)
    assert c.share is None and np.all(np.isfinite(c.nearest))


@pytest.mark.parametrize("seed", range(25))
def test_the_chaser_matches_its_scalar_reference_and_stays_in_the_area(seed):
    rng = np.random.default_rng(seed)
    T, N = int(rng.integers(1, 15)), int(rng.integers(1, 4))
    low, high = np.zeros(3), rng.uniform(20, 60, 3)
    truth = rng.uniform(-10, 70, (T, 3))  # partly outside the box: the chaser is clipped
    truth[rng.random(T) < 0.2] = np.nan
    initial = rng.uniform(0, 1, (N, 3)) * high
    step = float(rng.uniform(0, 8))
    got = chase(truth, initial, step, low, high)
    np.testing.assert_allclose(got, reference_chase(truth, initial, step, low, high), atol=1e-9)
    assert np.all(got >= low) and np.all(got <= high)
    before = np.concatenate([np.asarray(initial, float)[None], got[:-1]])
    assert np.all(np.linalg.norm(got - before, axis=2) <= step + 1e-9)


@pytest.mark.parametrize("seed", range(10))
def test_no_move_of_at_most_one_step_ends_nearer_than_the_straight_one(seed):
    rng = np.random.default_rng(seed)
    u, x, step = rng.uniform(0, 100, 3), rng.uniform(0, 100, 3), float(rng.uniform(0.5, 10))
    straight = np.linalg.norm(chase(x[None], u[None], step, LOW, HIGH)[0, 0] - x)
    dirs = rng.normal(size=(20000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    moves = u + dirs * rng.uniform(0, step, (20000, 1))
    assert np.linalg.norm(moves - x, axis=1).min() >= straight - 1e-9


def test_at_the_default_distance_a_top_power_agent_detects_about_half_the_time():
    ant = antenna_model(load_scenario("paper-fig3"))
    u = np.array([50.0, 50.0, 50.0])
    x = u + np.array([0.0, 0.0, NEAR])
    p = float(detection_probability(x, u, x, ant.l_max, ant))
    assert p == pytest.approx(0.95 * (6 / 8) ** 2) and 0.5 < p < 0.55


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="d must be"):
        clairvoyant_ceiling(line([1.0]), [True], [[0.0, 0, 0]], 5.0, LOW, HIGH, d=0.0)
    with pytest.raises(ValueError, match="max_step"):
        chase(line([1.0]), [[0.0, 0, 0]], -1.0, LOW, HIGH)
    with pytest.raises(ValueError, match="true position"):
        clairvoyant_ceiling(line([np.nan]), [True], [[0.0, 0, 0]], 5.0, LOW, HIGH)
