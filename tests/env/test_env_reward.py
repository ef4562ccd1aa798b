"""The environment's reward: Xi^N_n (checked against the sum over subsets) less the penalty
for Eq. (13)'s violations (checked in closed form)."""

import itertools

import numpy as np
import pytest

from trackjam.env.reward import reward_terms, team_reward, violation


def xi_by_subsets(p, n):
    """P(at least n of N detect), by summing over every subset of detecting agents."""
    total = 0.0
    for detect in itertools.product([0, 1], repeat=len(p)):
        if sum(detect) >= n:
            total += np.prod([pj if d else 1 - pj for pj, d in zip(p, detect)])
    return total


def test_violation_is_zero_below_delta_and_one_plus_decades_above():
    delta = 1e-4
    v = violation(np.array([0.0, 0.99e-4, 1e-4, 1e-3, 0.1]), delta)
    assert v.tolist() == pytest.approx([0.0, 0.0, 1.0, 2.0, 4.0])


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_reward_is_the_at_least_n_probability_less_the_penalty(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        p = rng.uniform(0, 1, size=4)
        R = rng.choice([0.0, 5e-5, 2e-4, 3e-2], size=4)
        lam = rng.uniform(0, 2)
        expected = xi_by_subsets(p, n) - lam * sum(1 + np.log10(r / 1e-4) for r in R if r >= 1e-4)
        xi, v = reward_terms(p, R, 1e-4, n)
        assert xi == pytest.approx(xi_by_subsets(p, n), abs=1e-12)
        assert team_reward(xi, v, lam) == pytest.approx(expected, abs=1e-12)


def test_no_penalty_weight_leaves_xi():
    assert team_reward(*reward_terms([0.5, 0.5], [1.0, 1.0], 1e-4, 1), 0.0) == pytest.approx(0.75)
