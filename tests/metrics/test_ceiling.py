"""The clairvoyant-chaser ceiling: agents that run straight at the true target."""

import json
import math

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.metrics.ceiling import NEAR, chase, clairvoyant_ceiling, team_ceiling, team_chase, team_goals
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
    with pytest.raises(ValueError, match="d: must be"):
        clairvoyant_ceiling(line([1.0]), [True], [[0.0, 0, 0]], 5.0, LOW, HIGH, d=0.0)
    with pytest.raises(ValueError, match="max_step"):
        chase(line([1.0]), [[0.0, 0, 0]], -1.0, LOW, HIGH)
    with pytest.raises(ValueError, match="true position"):
        clairvoyant_ceiling(line([np.nan]), [True], [[0.0, 0, 0]], 5.0, LOW, HIGH)


# Several targets: the chasers shared out, every present target first given one of its own.


def reference_goals(u, targets):
    """team_goals in scalar Python: all (agent, target) pairs sorted by distance, then agent, then
    target; a pair is taken when its agent is free and its target has no chaser; then the free
    agents go to their nearest present target (the first of equals)."""
    live = [k for k, x in enumerate(targets) if not any(math.isnan(v) for v in x)]
    if not live:
        return [-1] * len(u)
    dist = lambda j, k: math.dist(u[j], targets[k])  # noqa: E731
    goals, taken = [-1] * len(u), set()
    for _, j, k in sorted((dist(j, k), j, k) for j in range(len(u)) for k in live):
        if goals[j] < 0 and k not in taken:
            goals[j] = k
            taken.add(k)
    return [g if g >= 0 else min(live, key=lambda k: (dist(j, k), k)) for j, g in enumerate(goals)]


@pytest.mark.parametrize("seed", range(40))
def test_the_share_out_matches_its_scalar_reference(seed):
    rng = np.random.default_rng(seed)
    N, K = int(rng.integers(1, 7)), int(rng.integers(1, 5))
    u = rng.uniform(0, 100, (N, 3))
    x = rng.uniform(0, 100, (K, 3))
    x[rng.random(K) < 0.25] = np.nan
    if seed % 5 == 0:  # ties: agents on a grid, targets at equal distances
        u, x = np.round(u / 50) * 50, np.round(x / 50) * 50
    goals = team_goals(u, x)
    assert list(goals) == reference_goals(u.tolist(), x.tolist())
    live = np.flatnonzero(np.isfinite(x).all(axis=1))
    if len(live):  # every present target has a chaser when there are agents enough, and only those
        assert set(goals) <= set(live) and len(set(goals)) == min(N, len(live))
    else:
        assert np.all(goals == -1)


def test_each_of_two_targets_keeps_its_own_chaser_and_the_third_agent_the_nearer_one():
    x = np.array([[20.0, 50.0, 50.0], [80.0, 50.0, 50.0]])
    u = np.array([[10.0, 50.0, 50.0], [90.0, 50.0, 50.0], [40.0, 50.0, 50.0]])
    # agent 2 is nearer target 0 than agent 0 is, so it takes it; agent 0 then serves its nearest
    assert list(team_goals(u, x)) == [0, 1, 0]
    # two still targets, one chaser each, D m off: the nearest closes as max(0, D - k v)
    T, D, v = 6, 20.0, 5.0
    truth = np.repeat(x[None], T, axis=0)
    c = team_ceiling(truth, np.ones((T, 2), bool), x + [[-D, 0, 0], [0, D, 0]], v, LOW, HIGH, d=8.0)
    k = np.arange(1, T + 1)
    np.testing.assert_allclose(c.nearest, np.stack([np.maximum(0, D - k * v)] * 2, axis=1), atol=1e-12)
    assert c.shares == [4 / 6, 4 / 6] and c.total == 4 / 6


def test_one_chaser_between_two_targets_serves_one_and_the_other_is_never_reached():
    x = np.array([[30.0, 50.0, 50.0], [71.0, 50.0, 50.0]])
    c = team_ceiling(np.repeat(x[None], 10, axis=0), np.ones((10, 2), bool), [[50.0, 50.0, 50.0]], 5.0, LOW, HIGH)
    assert c.shares == [1.0 - 2 / 10, 0.0]  # 15, 10 then within 8 m: 8 of 10 steps; 21 m and more for the other
    assert c.total == pytest.approx(8 / 20)


def test_a_target_absent_or_hidden_is_not_counted_and_a_missing_one_is_not_chased():
    x0, x1 = [20.0, 50.0, 50.0], [50.0, 50.0, 50.0]
    truth = np.array([[x0, [np.nan] * 3], [x0, [np.nan] * 3], [x0, x1]])  # target 1 appears at step 3
    detectable = np.array([[True, False], [False, False], [True, True]])  # target 0 hidden at step 2
    u0 = [[10.0, 50.0, 50.0], [50.0, 50.0, 30.0]]
    c = team_ceiling(truth, detectable, u0, 5.0, LOW, HIGH)
    # both chase target 0 while it is the only one present, hidden or not; at step 3 agent 0 sits on
    # it (the nearest pair) and agent 1 turns to target 1
    np.testing.assert_allclose(c.positions[:, 0], reference_chase([x0] * 3, [u0[0]], 5.0, LOW, HIGH)[:, 0])
    np.testing.assert_allclose(c.positions[:, 1], reference_chase([x0, x0, x1], [u0[1]], 5.0, LOW, HIGH)[:, 0])
    assert np.isnan(c.nearest[0, 1]) and np.isnan(c.nearest[1, 1])
    far = np.linalg.norm(c.positions[2, 1] - x1)
    assert c.nearest[2, 1] == pytest.approx(far) and far > NEAR
    assert c.shares == [1.0, 0.0] and c.total == 2 / 3  # target 0: 5 m and 0 m; target 1 out of reach
    never = team_ceiling(truth, np.zeros((3, 2), bool), [[0.0, 0, 0]], 5.0, LOW, HIGH)
    assert never.shares == [None, None] and never.total is None


@pytest.mark.parametrize("seed", range(15))
def test_with_one_target_the_team_ceiling_is_the_chasers_ceiling(seed):
    rng = np.random.default_rng(seed)
    T, N = int(rng.integers(1, 20)), int(rng.integers(1, 5))
    truth = rng.uniform(0, 100, (T, 3)).cumsum(axis=0) % 100
    truth[rng.random(T) < 0.2] = np.nan
    detectable = np.isfinite(truth).all(axis=1) & (rng.random(T) < 0.8)
    initial = rng.uniform(0, 100, (N, 3))
    one = clairvoyant_ceiling(truth, detectable, initial, 5.0, LOW, HIGH)
    team = team_ceiling(truth[:, None], detectable[:, None], initial, 5.0, LOW, HIGH)
    np.testing.assert_array_equal(team.positions, one.positions)
    np.testing.assert_allclose(team.positions, reference_chase(truth, initial, 5.0, LOW, HIGH), atol=1e-9)
    np.testing.assert_array_equal(team.nearest[:, 0], one.nearest)
    assert team.shares == [one.share] and team.total == one.share


def test_bad_team_arguments_are_refused():
    x = np.zeros((2, 1, 3))
    with pytest.raises(ValueError, match="max_step"):
        team_chase(x, [[0.0, 0, 0]], -1.0, LOW, HIGH)
    with pytest.raises(ValueError, match="d: must be"):
        team_ceiling(x, np.ones((2, 1), bool), [[0.0, 0, 0]], 5.0, LOW, HIGH, d=-1.0)
    with pytest.raises(ValueError, match=r"\(T, K, 3\)"):
        team_ceiling(np.zeros((2, 3)), np.ones((2, 1), bool), [[0.0, 0, 0]], 5.0, LOW, HIGH)
    with pytest.raises(ValueError, match="true position"):
        team_ceiling(np.full((1, 1, 3), np.nan), np.ones((1, 1), bool), [[0.0, 0, 0]], 5.0, LOW, HIGH)


@pytest.mark.parametrize("seed", range(30))
def test_the_share_out_breaks_exact_ties_by_agent_then_target(seed):
    """Agents and targets on the corners of a 10 m cube: most (agent, target) distances tie
    exactly (squares of whole numbers), and with 18 pairs or more an unstable sort of them picks
    other pairs than "ties by agent, then target" (the scalar reference's sorted tuples)."""
    rng = np.random.default_rng(1000 + seed)
    N, K = int(rng.integers(6, 9)), int(rng.integers(3, 5))
    u = 10.0 * rng.integers(0, 2, (N, 3))
    x = 10.0 * rng.integers(0, 2, (K, 3))
    assert list(team_goals(u, x)) == reference_goals(u.tolist(), x.tolist())


@pytest.mark.parametrize("offset, share", [(NEAR, 1.0), (NEAR + 0.5, 0.0)])
def test_a_chaser_exactly_d_away_counts_as_near(offset, share):
    """"Within d" includes d itself: a chaser that cannot move (max_step 0) sits exactly 8 m off
    (50 - 42, exact in floating point) at every step; 8.5 m off it never counts."""
    truth = line([50.0] * 3)
    c = clairvoyant_ceiling(truth, [True] * 3, [[50.0 - offset, 50.0, 50.0]], 0.0, LOW, HIGH)
    np.testing.assert_array_equal(c.nearest, np.full(3, offset))
    assert c.share == share
