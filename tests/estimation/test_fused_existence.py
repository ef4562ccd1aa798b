"""The two rules for the team's existence: the paper's mean, and evidence (ours)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.estimation.fusion import fused_existence

prob = st.floats(0.001, 0.999)


def odds(e):
    return e / (1 - e)


def test_mean_rule_is_the_papers_mean():
    assert fused_existence([0.2, 0.9, 0.7], rule="mean") == pytest.approx(0.6)


@settings(max_examples=100, deadline=None)
@given(prior=prob, posts=st.lists(prob, min_size=1, max_size=5))
def test_evidence_rule_multiplies_the_likelihood_ratios_on_the_common_prior(prior, posts):
    fused = fused_existence(posts, [prior] * len(posts), rule="evidence")
    expected = odds(prior) * np.prod([odds(e) / odds(prior) for e in posts])
    assert fused == pytest.approx(expected / (1 + expected), rel=1e-9, abs=1e-12)
    assert 0.0 <= fused <= 1.0


def test_one_agent_keeps_its_own_posterior_under_either_rule():
    assert fused_existence([0.73], [0.4], rule="evidence") == pytest.approx(0.73)
    assert fused_existence([0.73], [0.4], rule="mean") == pytest.approx(0.73)


def test_three_agreeing_misses_count_three_times():
    prior, post = 0.98, 0.85  # each agent's miss alone lowers 0.98 to 0.85
    assert fused_existence([post] * 3, [prior] * 3, rule="evidence") < 0.5 < fused_existence([post] * 3, rule="mean")


def test_agents_that_learned_nothing_do_not_dilute_the_evidence():
    assert fused_existence([0.9, 0.3, 0.3], [0.3] * 3, rule="evidence") == pytest.approx(0.9)
    assert fused_existence([0.9, 0.3, 0.3], rule="mean") == pytest.approx(0.5)


def test_unknown_rule_is_refused():
    with pytest.raises(ValueError):
        fused_existence([0.5], rule="max")
