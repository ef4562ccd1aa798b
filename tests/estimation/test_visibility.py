"""The hidden-target mode (filter.visibility), evidence fusion with it, and a filter updated with
its teammates' scans (fusion.share: scans): closed forms on a point-mass particle set."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.config import load_scenario
from trackjam.estimation.bernoulli import Scan, mix_visibility, posterior_visibility
from trackjam.estimation.fusion import fused_existence, fused_visible
from trackjam.radio.antenna import axis_of
from trackjam.simulation.build import antenna_model, make_filter

HIDE, REAPPEAR = 0.1, 0.3
U1 = np.array([10.0, 10.0, 10.0])
U2 = np.array([20.0, 8.0, 12.0])
TARGET = U1 + 5.0 * axis_of(U1, np.array([14.0, 13.0, 12.0]))  # 5 m from U1: p_D = p_D^max (R_0 = 6 m)
P_D = 0.95

prob = st.floats(0.001, 0.999)


def point_filter(visibility=True, existence=0.9):
    """A filter whose every particle sits still at TARGET, with no birth: p_D is the same for all."""
    s = load_scenario(
        "paper-fig3", filter__birth_prob=0.0, filter__accel_var=0.0, filter__particles=200, filter__birth_particles=20,
        filter__visibility={"hide": HIDE, "reappear": REAPPEAR} if visibility else None,
    )
    f = make_filter(s, np.random.default_rng(3))
    f.reset_to(existence, np.concatenate([TARGET, np.zeros(3)]), np.zeros((6, 6)))
    return f, antenna_model(s)


def test_mixing_is_the_two_branch_sum():
    log_L = np.log(np.array([0.05, 1.0, 40.0]))
    np.testing.assert_allclose(np.exp(mix_visibility(log_L, 0.7)), 0.7 * np.exp(log_L) + 0.3, rtol=1e-13)
    assert mix_visibility(log_L, 1.0) is log_L
    np.testing.assert_array_equal(mix_visibility(log_L, 0.0), 0.0)
    assert posterior_visibility(0.7, math.log(0.05)) == pytest.approx(0.7 * 0.05 / (0.7 * 0.05 + 0.3))
    assert posterior_visibility(0.7, -np.inf) == 0.0
    assert posterior_visibility(1.0, math.log(0.05)) == 1.0


def test_a_miss_lowers_existence_less_when_the_target_may_be_hidden():
    """One miss at p_D = 0.95: the paper's filter multiplies the odds by 1 - p_D; with the hidden
    mode by nu (1 - p_D) + 1 - nu, nu = (1 - hide) after a certain visible start."""
    f, ant = point_filter()
    pred = f.predict()
    nu = 1.0 - HIDE
    assert f.nu_pred == pytest.approx(nu)
    assert pred.existence == pytest.approx(0.98 * 0.9)
    post = f.update(np.zeros((0, 3)), U1, TARGET, ant.l_max)
    ratio = nu * (1 - P_D) + 1 - nu
    e = pred.existence
    assert post.existence == pytest.approx(e * ratio / (1 - e + e * ratio), rel=1e-10)
    assert f.nu == pytest.approx(nu * (1 - P_D) / ratio, rel=1e-10)
    assert f.log_evidence == pytest.approx(math.log(1 - P_D), rel=1e-10)
    g, _ = point_filter(visibility=False)
    e0 = g.predict().existence
    paper = g.update(np.zeros((0, 3)), U1, TARGET, ant.l_max).existence
    assert paper == pytest.approx(e0 * (1 - P_D) / (1 - e0 + e0 * (1 - P_D)), rel=1e-10)
    assert paper < post.existence


def test_a_hidden_target_becomes_visible_again_at_the_reappear_rate():
    f, ant = point_filter()
    f.reset_to(0.9, visible=0.0)
    f.predict()
    assert f.nu_pred == pytest.approx(REAPPEAR)
    f.update(np.zeros((0, 3)), U1, TARGET, 0.0)  # antenna off: no evidence either way
    assert f.nu == pytest.approx(REAPPEAR)


@pytest.mark.parametrize("visibility", [False, True])
def test_teammates_scans_multiply_in_as_a_centralised_filter_would(visibility):
    """Two agents miss: the odds fall by nu (1 - p_D)^2 + 1 - nu (nu = 1 without the mode): one
    hidden target explains both misses at once."""
    f, ant = point_filter(visibility)
    e = f.predict().existence
    other = Scan.of(np.zeros((0, 3)), U2, TARGET, ant.l_max, ant)
    assert np.linalg.norm(U2 - TARGET) > ant.r0  # the teammate is farther: p_D = 0.95 (R_0 / eta)^2
    p2 = P_D * (ant.r0 / np.linalg.norm(U2 - TARGET)) ** 2
    post = f.update(np.zeros((0, 3)), U1, TARGET, ant.l_max, others=[other])
    nu = 1.0 - HIDE if visibility else 1.0
    ratio = nu * (1 - P_D) * (1 - p2) + 1 - nu
    assert post.existence == pytest.approx(e * ratio / (1 - e + e * ratio), rel=1e-10)
    assert f.log_evidence == pytest.approx(math.log((1 - P_D) * (1 - p2)), rel=1e-10)


@settings(max_examples=100, deadline=None)
@given(prior=prob, nu=prob, logs=st.lists(st.floats(-8.0, 8.0), min_size=1, max_size=5))
def test_fused_visible_is_the_joint_likelihood_ratio(prior, nu, logs):
    e, visible = fused_visible([prior] * len(logs), logs, [nu] * len(logs))
    V = math.exp(sum(logs))
    ratio = nu * V + 1 - nu
    odds = prior / (1 - prior) * ratio
    assert e == pytest.approx(odds / (1 + odds), rel=1e-9, abs=1e-12)
    assert visible == pytest.approx(nu * V / ratio, rel=1e-9, abs=1e-12)


def test_fused_visible_matches_the_evidence_rule_when_the_target_cannot_hide():
    prior, posts = 0.6, [0.9, 0.2, 0.7]
    logs = [math.log(p / (1 - p) / (prior / (1 - prior))) for p in posts]
    e, visible = fused_visible([prior] * 3, logs, [1.0] * 3)
    assert e == pytest.approx(fused_existence(posts, [prior] * 3, rule="evidence"), rel=1e-12)
    assert visible == 1.0


def test_three_misses_count_once_against_a_hidden_target():
    """The evidence rule alone drops a 0.98 track below 0.5 on three misses at p_D = 0.95; with
    the target possibly hidden (nu = 0.9) the track survives."""
    logs = [math.log(0.05)] * 3
    plain = fused_existence([0.98 * 0.05 / (1 - 0.98 + 0.98 * 0.05)] * 3, [0.98] * 3, rule="evidence")
    e, _ = fused_visible([0.98] * 3, logs, [0.9] * 3)
    assert plain < 0.5 < e
