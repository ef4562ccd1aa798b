"""`filter.visibility.per_particle` (ours): each particle carries its own P(visible). Checked
against the closed forms of the one-P(visible) mode, a brute-force sum over every visibility
path of a two-place belief, and a run of the `pursuit` preset."""

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.estimation.bernoulli import (
    mix_visibility,
    mix_visibility_per_particle,
    posterior_visibility,
    shift_visibility,
)
from trackjam.radio.antenna import axis_of
from trackjam.simulation.build import antenna_model, make_filter

HIDE, REAPPEAR = 0.1, 0.3
U = np.array([10.0, 10.0, 10.0])
INSIDE = U + 5.0 * axis_of(U, np.array([14.0, 13.0, 12.0]))  # on the antenna's axis, 5 m off: p_D = p_D^max
OUTSIDE = U - 5.0 * axis_of(U, np.array([14.0, 13.0, 12.0]))  # behind the agent: outside the cone, p_D = 0
P_D, P_S = 0.95, 0.98
N = 10_000


def two_place_filter(per_particle: bool, existence=0.9, share_inside=0.5):
    """A filter whose particles sit still, ``share_inside`` of the weight where the antenna sees
    them with p_D^max and the rest behind the agent, where it never sees them; no birth."""
    s = load_scenario(
        "paper-fig3", filter__birth_prob=0.0, filter__accel_var=0.0, filter__particles=N, filter__birth_particles=20,
        filter__visibility={"hide": HIDE, "reappear": REAPPEAR, "per_particle": per_particle},
    )
    f = make_filter(s, np.random.default_rng(5))
    f.reset_to(existence, np.concatenate([INSIDE, np.zeros(3)]), np.zeros((6, 6)))
    k = int(round(share_inside * N))
    f._X[k:, :3] = OUTSIDE
    return f, antenna_model(s)


def exact_misses(T: int, share_inside: float, e0: float):
    """Brute force over the 2^T visibility paths of a target that starts visible: after T
    misses, the weight inside the cone, P(visible | inside) and the existence."""
    lik = []  # P(misses 1..t | exists, inside), t = 0..T
    vis = []  # P(visible at t, misses 1..t | exists, inside)
    for t in range(T + 1):
        total = visible = 0.0
        for path in itertools.product((0, 1), repeat=t):  # 1: visible at that step
            p, prev = 1.0, 1
            for s in path:
                p *= ((1 - HIDE) if s else HIDE) if prev else (REAPPEAR if s else 1 - REAPPEAR)
                p *= (1 - P_D) if s else 1.0
                prev = s
            total += p
            visible += p if prev else 0.0
        lik.append(total)
        vis.append(visible)
    e = e0
    for t in range(1, T + 1):  # the Bernoulli recursion with the exact P(miss_t | exists, misses before)
        before = share_inside * lik[t - 1] + 1 - share_inside
        now = share_inside * lik[t] + 1 - share_inside
        e_pred = P_S * e
        e = e_pred * (now / before) / (1 - e_pred + e_pred * now / before)
    inside = share_inside * lik[T] / (share_inside * lik[T] + 1 - share_inside)
    return inside, vis[T] / lik[T], e


@pytest.mark.parametrize("T", [1, 2, 4])
def test_misses_match_the_sum_over_every_visibility_path(T):
    """Per particle, the hidden-target mode is the exact filter of (position, visible): after T
    misses the weight left where the antenna looks, each particle's P(visible) and the existence
    are the brute-force sums over the 2^T visibility paths. One P(visible) for the whole filter
    is not: from the second miss on it keeps less weight where the misses fell."""
    f, ant = two_place_filter(True)
    g, _ = two_place_filter(False)
    for _ in range(T):
        for h in (f, g):
            h.predict()
            h.update(np.zeros((0, 3)), U, INSIDE, ant.l_max)
    inside, nu_inside, e = exact_misses(T, 0.5, 0.9)
    at = np.linalg.norm(f.particles[:, :3] - INSIDE, axis=1) < 1e-9
    w = np.exp(f.log_w)
    assert float(w[at].sum()) == pytest.approx(inside, abs=2.0 / N)
    np.testing.assert_allclose(f._nu[at], nu_inside, rtol=1e-10)
    np.testing.assert_allclose(f._nu[~at], 1 - HIDE if T == 1 else f._nu[~at][0], rtol=1e-12)
    assert f.estimate().existence == pytest.approx(e, abs=2.0 / N)  # the resampled shares round to 1/N
    assert f.nu == pytest.approx(float(w @ f._nu), abs=2.0 / N)
    at_g = np.linalg.norm(g.particles[:, :3] - INSIDE, axis=1) < 1e-9
    kept = float(np.exp(g.log_w)[at_g].sum())
    if T == 1:
        assert kept == pytest.approx(inside, abs=2.0 / N)
    else:
        assert kept < inside - 0.01


def test_a_filter_that_never_looks_keeps_its_particles_visibility_at_the_chain():
    f, ant = two_place_filter(True)
    nu = 1.0
    for _ in range(3):
        f.predict()
        f.update(np.zeros((0, 3)), U, INSIDE, 0.0)  # antenna off: no evidence
        nu = (1 - HIDE) * nu + REAPPEAR * (1 - nu)
        np.testing.assert_allclose(f._nu, nu, rtol=1e-12)
        assert f.nu == pytest.approx(nu, rel=1e-12)


@settings(max_examples=100, deadline=None)
@given(nu=st.floats(0.0, 1.0), logs=st.lists(st.floats(-30.0, 8.0), min_size=1, max_size=6),
       raw=st.lists(st.floats(0.01, 1.0), min_size=6, max_size=6))
def test_one_visibility_for_every_particle_is_the_filter_wide_mode(nu, logs, raw):
    log_L = np.array(logs)
    w = np.array(raw[:len(logs)])
    w /= w.sum()
    log_Lm, nu_post, log_V = mix_visibility_per_particle(np.log(w), log_L, np.full(len(logs), nu))
    np.testing.assert_allclose(log_Lm, mix_visibility(log_L, nu), rtol=1e-12, atol=1e-12)
    if 0.0 < nu:
        assert log_V == pytest.approx(math.log(float(w @ np.exp(log_L))), rel=1e-9, abs=1e-9)
    mean_post = float((w * np.exp(log_Lm)) @ nu_post / (w @ np.exp(log_Lm)))
    assert mean_post == pytest.approx(posterior_visibility(nu, float(np.log(w @ np.exp(log_L)))), abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(nus=st.lists(st.floats(0.0, 1.0), min_size=2, max_size=8), logs=st.lists(st.floats(-30.0, 8.0), min_size=8,
                                                                                  max_size=8))
def test_the_evidence_sent_to_fusion_gives_the_filters_own_likelihood(nus, logs):
    """Evidence fusion mixes one nu with V: nu_bar V + 1 - nu_bar must equal sum_i w_i L'_i."""
    nu = np.array(nus)
    log_L = np.array(logs[:len(nus)])
    w = np.full(len(nus), 1.0 / len(nus))
    log_Lm, nu_post, log_V = mix_visibility_per_particle(np.log(w), log_L, nu)
    nu_bar = float(w @ nu)
    assert float(w @ np.exp(log_Lm)) == pytest.approx(nu_bar * math.exp(log_V) + 1 - nu_bar, rel=1e-9, abs=1e-12)
    assert np.all((0.0 <= nu_post) & (nu_post <= 1.0))
    np.testing.assert_array_equal(nu_post[nu == 0.0], 0.0)
    np.testing.assert_array_equal(nu_post[nu == 1.0], 1.0)


def test_fusion_feedback_shifts_every_particles_visibility_to_the_teams():
    rng = np.random.default_rng(1)
    nu = rng.uniform(0, 1, 50)
    w = rng.uniform(0, 1, 50)
    w /= w.sum()
    for target in (0.05, 0.5, 0.93):
        out = shift_visibility(nu, w, target)
        assert float(w @ out) == pytest.approx(target, abs=1e-9)
        assert np.array_equal(np.argsort(out, kind="stable"), np.argsort(nu, kind="stable"))
    np.testing.assert_array_equal(shift_visibility(nu, w, 0.0), 0.0)
    np.testing.assert_array_equal(shift_visibility(nu, w, 1.0), 1.0)
    f, ant = two_place_filter(True)
    f.predict()
    f.update(np.zeros((0, 3)), U, INSIDE, ant.l_max)
    f.reset_to(0.8, visible=0.4)
    assert float(np.exp(f.log_w) @ f._nu) == pytest.approx(0.4, abs=1e-9)
    f.reset_to(0.8, np.concatenate([INSIDE, np.zeros(3)]), np.eye(6), visible=0.6)  # redrawn: one value
    np.testing.assert_array_equal(f._nu, 0.6)


def test_the_pursuit_preset_runs_with_it_and_keeps_one_visibility_per_particle():
    from trackjam.simulation.engine import Simulation

    sim = Simulation(load_scenario("pursuit", steps=20, filter__visibility__per_particle=True))
    seen_below = False
    for _ in range(20):
        sim.step()
        for agent in sim.team.agents:
            f = agent.filter
            assert f._nu.shape == (len(f._X),)
            assert np.all((0.0 <= f._nu) & (f._nu <= 1.0))
            if f._young is not None:
                assert f._young.nu.shape == (len(f._young.X),)
            nu_all = f._nu if f._young is None else np.concatenate([f._nu, f._young.nu])
            assert f.nu == pytest.approx(float(np.exp(f.log_w) @ nu_all), abs=3e-3)  # before resampling, and after
            seen_below |= bool(f._nu.min() < 0.5 < f._nu.max())
    assert seen_below  # the occlusion (steps 14-17) leaves particles the scans missed believed hidden


def test_a_value_that_is_not_a_boolean_is_one_line_naming_the_key():
    with pytest.raises(ConfigError, match=r"filter\.visibility\.per_particle"):
        load_scenario("pursuit", overrides=["filter.visibility.per_particle=maybe"])


def test_the_particles_visibility_is_predicted_by_the_chain_and_none_without_the_option():
    f, ant = two_place_filter(True)
    f.predict()
    f.update(np.zeros((0, 3)), U, INSIDE, ant.l_max)
    posterior = f.visible.copy()
    np.testing.assert_array_equal(posterior, f._nu)
    f.predict()
    np.testing.assert_allclose(f.visible, (1 - HIDE) * posterior + REAPPEAR * (1 - posterior), rtol=1e-12)
    assert f.visible.shape == (len(f.particles),)
    g, _ = two_place_filter(False)
    assert g.visible is None


def test_planning_over_the_belief_samples_where_the_target_can_be_seen():
    """The planning sample of `control.plan_over: belief` weighs each particle by its P(visible):
    Eq. (12)'s chance of detection is nu_i p_D(x_i), so after two misses inside the cone the sample
    draws fewer points there than the weights alone would, as many as w_i nu_i asks."""
    from trackjam.control.planning import belief_sample
    from trackjam.simulation.agent import Agent

    f, ant = two_place_filter(True)
    for _ in range(2):
        f.predict()
        f.update(np.zeros((0, 3)), U, INSIDE, ant.l_max)
    agent = Agent.create(0, U, INSIDE, f, None, np.random.SeedSequence(1), np.random.SeedSequence(2))
    k = 64
    sample = agent.predict(3, 0.5, belief_samples=k).belief
    inside = np.linalg.norm(f.particles[:, :3] - INSIDE, axis=1) < 1e-9
    w = np.exp(f.log_w)
    share_w = float(w[inside].sum())
    share_wnu = float((w * f.visible)[inside].sum() / (w @ f.visible))
    got = float(np.mean(np.linalg.norm(sample - INSIDE, axis=1) < 1e-9))
    assert got == pytest.approx(share_wnu, abs=1.0 / k)
    assert share_wnu < share_w - 2.0 / k  # the weights alone would have drawn more points inside
    np.testing.assert_array_equal(belief_sample(f.particles, w * f.visible, k), sample)
