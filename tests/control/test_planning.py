"""Where an agent plans: the belief sample it sends, and the team's pooled planning sample."""

import numpy as np

from trackjam.config import load_scenario
from trackjam.control.planning import belief_sample, pooled_belief
from trackjam.simulation.loop import simulate


def test_the_sample_takes_the_weights_quantiles():
    X = np.arange(30.0).reshape(10, 3)
    w = np.zeros(10)
    w[7] = 1.0
    assert np.array_equal(belief_sample(X, w, 4), np.repeat(X[7:8], 4, axis=0))
    assert np.array_equal(belief_sample(X, np.ones(10), 10), X)
    # weights 1:3 over two particles: a quarter of the quantiles fall on the first
    got = belief_sample(X[:2], np.array([1.0, 3.0]), 8)
    assert (got == X[0]).all(axis=1).sum() == 2 and (got == X[1]).all(axis=1).sum() == 6


def test_each_agent_carries_an_equal_share_of_the_pooled_weight():
    a, b = np.zeros((4, 3)), np.ones((2, 3))
    samples, weights = pooled_belief([a, b])
    assert samples.shape == (6, 3)
    assert np.isclose(weights.sum(), 1.0)
    assert np.isclose(weights[:4].sum(), 0.5) and np.isclose(weights[4:].sum(), 0.5)


def test_a_team_planning_over_the_belief_is_proven_optimal_for_the_average():
    common = ["control.solver=exact", "steps=6", "filter.particles=500", "filter.birth_particles=100"]
    point = simulate(load_scenario("paper-fig3", common))
    belief = simulate(load_scenario("paper-fig3", common + ["control.plan_over=belief", "control.belief_samples=8"]))
    tracking = belief.steps["mode"] == "track"
    assert tracking.any() and np.all(belief.steps["optimal"][tracking])
    # Xi averaged over where the target may be is below Xi at its predicted mean on some step
    both = tracking & (point.steps["mode"] == "track")
    assert np.any(belief.steps["objective"][both] != point.steps["objective"][both])
