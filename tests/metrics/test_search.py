"""The reach-free searcher after an occlusion (metrics/search.py): its detection model against
Eq. (9), its placement against optima found by hand, its Bayes weights, and the Kalman floor
against a simulated Kalman filter's errors."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.metrics.search import fresh_placement, kalman_floor, miss_probability, place, search_after
from trackjam.radio.antenna import detection_probability
from trackjam.simulation.build import antenna_model

ANT = antenna_model(load_scenario("pursuit"))  # 80 deg cone, R0 = 6 m, p_D^max = 0.95, height 40 m
LOW, HIGH = np.zeros(3), np.full(3, 100.0)


def test_the_miss_probability_is_the_product_of_eq_9_over_the_agents():
    rng = np.random.default_rng(0)
    P = rng.uniform(30, 70, (500, 3))
    U = rng.uniform(30, 70, (3, 3))
    A = rng.uniform(30, 70, (3, 3))
    expected = np.ones(len(P))
    for u, a in zip(U, A):
        for i, p in enumerate(P):
            expected[i] *= 1.0 - float(detection_probability(p, u, a, ANT.l_max, ANT))
    assert np.allclose(miss_probability(P, U, A, ANT), expected, rtol=0, atol=1e-12)
    assert (expected < 1).any() and (expected == 1).any()  # some points inside a cone, some outside


def test_a_point_belief_is_covered_by_every_agent_at_the_top_detection_probability():
    x = np.array([50.0, 50.0, 50.0])
    P, w = np.tile(x, (50, 1)), np.full(50, 1 / 50)
    start = fresh_placement(x, 3)  # 10 m off: p_D = 0.95 (6/10)^2 each
    assert w @ (1 - miss_probability(P, *start, ANT)) == pytest.approx(1 - (1 - 0.95 * 0.36) ** 3)
    U, A, v = place(P, w, [start], ANT, np.random.default_rng(1))
    assert v == pytest.approx(1 - 0.05**3, abs=1e-9)  # within R0 inside each cone: p_D^max
    assert np.linalg.norm(U - x, axis=1).max() <= ANT.r0 + 1e-9


@pytest.mark.parametrize("agents, best", [(1, 0.7 * 0.95), (2, 0.95)])
def test_two_far_points_one_agent_covers_the_heavier_two_cover_both(agents, best):
    """Points 200 m apart (the cone is 40 m deep), weights 0.7 and 0.3: one agent covers one point
    at most, so 0.7 p_D^max is the optimum; two cover both."""
    a, b = np.array([20.0, 50, 50]), np.array([220.0, 50, 50])
    P = np.vstack([np.tile(a, (7, 1)), np.tile(b, (3, 1))])
    w = np.full(10, 0.1)
    starts = [(np.vstack([a + [8.0, 0, 0], b + [8.0, 0, 0]])[:agents], np.vstack([a, b])[:agents])]
    U, A, v = place(P, w, starts, ANT, np.random.default_rng(2), iterations=300)
    assert v == pytest.approx(best, abs=1e-9)


def test_the_searcher_finds_a_slow_target_it_was_told_at_once_and_repeats_from_its_seed():
    """No motion noise and the true state told: the belief is the truth, and its agents
    detect it at the first detectable step with probability 1 - 0.05^3."""
    T = 12
    states = [None] + [np.array([40.0 + t, 50.0, 50.0, 1.0, 0.0, 0.0]) for t in range(1, T + 1)]
    detectable = np.array([False] + [not 5 <= t <= 8 for t in range(1, T + 1)])
    runs = [search_after(states, detectable, 4, ANT, 1e-12, LOW, HIGH, np.random.default_rng(3), particles=200)
            for _ in range(2)]
    found = runs[0]
    assert found.first == 9 and list(found.searched) == [9]  # the hidden steps 5-8 are not searched
    assert found.chance[0] == pytest.approx(1 - 0.05**3, abs=1e-6)
    assert found.truth_chance[0] == pytest.approx(1 - 0.05**3, abs=1e-6)
    again = runs[1]
    assert again.first == found.first and np.array_equal(again.searched, found.searched)
    assert np.array_equal(again.chance, found.chance) and np.array_equal(again.truth_chance, found.truth_chance)


def test_misses_move_the_belief_away_from_where_the_agents_looked():
    """A target told with a wide spread and never detectable where the searcher looks first:
    after each miss the planned chance falls below what a fresh belief of the same spread gives,
    and every step after the hidden ones is searched until the end."""
    T = 16
    states = [None] + [np.array([50.0, 50.0, 50.0, 0.0, 0.0, 0.0]) for _ in range(T)]
    detectable = np.array([False] + [t <= 3 or t >= 6 for t in range(1, T + 1)])
    rng = np.random.default_rng(4)
    found = search_after(states, detectable, 3, ANT, 0.5, LOW, HIGH, rng, sd=(3.0, 1.0), particles=400,
                         iterations=60)
    if found.first is None:
        assert list(found.searched) == list(range(6, T + 1))
    else:
        assert list(found.searched) == list(range(6, found.first + 1))
    assert np.all((found.chance > 0) & (found.chance <= 1)) and np.all((found.truth_chance >= 0) & (found.truth_chance <= 1))


def test_a_step_with_no_target_cannot_be_the_last_seen():
    states = [None, None, np.zeros(6), np.zeros(6)]
    with pytest.raises(ValueError, match="last_seen"):
        search_after(states, np.array([False, False, True, True]), 1, ANT, 0.5, LOW, HIGH, np.random.default_rng(0))


def test_the_kalman_floor_is_the_spread_of_a_simulated_kalman_filters_errors():
    """One axis of Eq. (1), q = 0.5, a position fix of 0.35 m each step: the errors of 4,000
    simulated filters after 60 steps have the floor's spread (to 5 %)."""
    q, r, n = 0.5, 0.35, 4000
    rng = np.random.default_rng(5)
    Phi, G = np.array([[1.0, 1.0], [0.0, 1.0]]), np.array([0.5, 1.0])
    x = np.zeros((n, 2))
    xh, P = np.zeros((n, 2)), np.diag([1e4, 1e4])
    for _ in range(60):
        x = x @ Phi.T + rng.normal(0, np.sqrt(q), (n, 1)) * G
        xh = xh @ Phi.T
        P = Phi @ P @ Phi.T + q * np.outer(G, G)
        K = P[:, 0] / (P[0, 0] + r * r)
        z = x[:, 0] + rng.normal(0, r, n)
        xh = xh + np.outer(z - xh[:, 0], K)
        P = P - np.outer(K, P[0])
    err = (xh - x).std(axis=0)
    floor = kalman_floor(q, r)
    assert err == pytest.approx(floor, rel=0.05)
    assert kalman_floor(q, 2 * r)[1] > floor[1]  # a worse fix, a worse velocity


def test_a_searcher_bound_by_its_moves_never_moves_further_than_its_reach():
    """Agents start 40 m behind a slow target and move at most 5 m a step: each step's placement
    stays within 5 m of the last one, and they close in."""
    from trackjam.metrics import search as sm

    T = 14
    states = [None] + [np.array([50.0 + 0.5 * t, 50.0, 50.0, 0.5, 0.0, 0.0]) for t in range(1, T + 1)]
    detectable = np.array([False] + [t != 3 for t in range(1, T + 1)])
    start = np.array([[10.0, 50, 50], [10.0, 55, 50], [10.0, 45, 50]])
    moves = []
    real_place = sm.place

    def spy(*args, **kwargs):
        U, A, v = real_place(*args, **kwargs)
        moves.append(U)
        return U, A, v

    sm.place = spy
    try:
        found = sm.search_after(states, detectable, 2, ANT, 1e-6, LOW, HIGH, np.random.default_rng(6),
                                particles=200, iterations=60, positions=start, reach=5.0)
    finally:
        sm.place = real_place
    track = np.vstack([start[None], np.array(moves)])
    assert np.linalg.norm(np.diff(track, axis=0), axis=2).max() <= 5.0 + 1e-9
    assert len(moves) >= 2  # the hidden step 3 is a move too
    # they close in on the target (every move counts: 5 m a step against its 0.5)
    t_last = 2 + len(moves)
    gap = np.linalg.norm(track[-1] - states[t_last][:3], axis=1).min()
    assert gap < np.linalg.norm(start - states[2][:3], axis=1).min() - 3.0 * len(moves)
    assert found.first is None or found.first == found.searched[-1]
    with pytest.raises(ValueError, match="reach"):
        sm.search_after(states, detectable, 2, ANT, 0.5, LOW, HIGH, np.random.default_rng(0), positions=start)


def test_without_free_aims_every_antenna_stays_on_the_starts_aim():
    rng = np.random.default_rng(7)
    P = rng.normal(50.0, 4.0, (300, 3))
    w = np.full(300, 1 / 300)
    mean = w @ P
    start = fresh_placement(mean, 3)
    U, A, v = place(P, w, [start], ANT, rng, iterations=80, aims_free=False)
    assert np.array_equal(A, np.tile(mean, (3, 1))) and not np.array_equal(U, start[0])
    U2, A2, v2 = place(P, w, [start], ANT, np.random.default_rng(7), iterations=80)
    assert not np.array_equal(A2, A)  # with free aims they move


def test_a_searcher_that_does_not_know_the_target_is_hidden_searches_the_hidden_steps_in_vain():
    T = 12
    states = [None] + [np.array([50.0, 50.0, 50.0, 0.0, 0.0, 0.0]) for _ in range(T)]
    detectable = np.array([False] + [not 5 <= t <= 8 for t in range(1, T + 1)])
    found = search_after(states, detectable, 4, ANT, 1e-12, LOW, HIGH, np.random.default_rng(8), particles=100,
                         iterations=40, knows_hidden=False)
    assert list(found.searched[:4]) == [5, 6, 7, 8]  # looked while it was hidden ...
    assert np.all(found.truth_chance[:4] == 0.0) and found.chance[0] > 0.9  # ... where it was, and missed
    assert found.first is None or found.first >= 9
