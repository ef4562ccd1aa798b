"""x_bar of Eq. (12) by hand: the mean of the predicted positions of the agents whose predicted
existence e_{t|t-1} exceeds 0.5, strictly. The boundary matters: with the paper's p_b = 0.02 and
p_s = 0.98 the prediction's fixed point is exactly p_b / (p_b + 1 - p_s) = 0.5, so an agent that
knows nothing sits at (or just below) 0.5 and must not place the aim."""

import numpy as np

from trackjam.control.planning import planning_aim
from trackjam.control.pursuit import AimSettings, pursuit_aim
from trackjam.estimation.bernoulli import Estimate


def est(e, x):
    return Estimate(e, np.array([*x, 1.0, -2.0, 0.5]), np.eye(6))


def test_x_bar_is_the_mean_of_the_believers_predicted_positions():
    predicted = [est(0.9, [10, 20, 30]), est(0.5, [90, 90, 90]), est(0.51, [20, 40, 60]), est(0.1, [0, 0, 0])]
    np.testing.assert_allclose(planning_aim(predicted), [15.0, 30.0, 45.0], rtol=0, atol=1e-12)
    got = pursuit_aim(predicted, np.zeros((4, 3)), AimSettings(), np.zeros(3), np.full(3, 100.0))
    np.testing.assert_allclose(got, [15.0, 30.0, 45.0], rtol=0, atol=1e-12)


def test_an_agent_at_exactly_one_half_does_not_believe():
    e_fixed = 0.02 * (1 - 0.5) + 0.98 * 0.5  # the prediction's fixed point, exactly 0.5 in floating point
    assert e_fixed == 0.5
    assert planning_aim([est(e_fixed, [50, 50, 50]), est(0.3, [10, 10, 10])]) is None
    assert pursuit_aim([est(e_fixed, [50, 50, 50])], np.zeros((1, 3)), AimSettings(), np.zeros(3),
                       np.full(3, 100.0)) is None
