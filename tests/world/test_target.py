"""The truth target: Eq. (1), its existence, occlusions, walls and jamming response."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.world.motion import cv_matrices, cv_step
from trackjam.simulation.build import target_params
from trackjam.world.target import TruthTarget, reflect


def test_cv_sample_covariance_matches_phi_p_phi_plus_gamma_q_gamma():
    Phi, Gamma = cv_matrices(1.0)
    rng = np.random.default_rng(3)
    P = np.diag([1.0, 2.0, 0.5, 0.3, 0.2, 0.1])
    x0 = rng.multivariate_normal(np.zeros(6), P, size=200000)
    x1 = cv_step(x0, rng, 0.5)
    expected = Phi @ P @ Phi.T + 0.5 * Gamma @ Gamma.T
    assert np.allclose(np.cov(x1.T), expected, atol=0.04)
    assert np.allclose(x1.mean(axis=0), 0, atol=0.02)


def test_cv_without_noise_is_constant_velocity():
    x = np.array([1.0, 2, 3, 0.5, -1, 2])
    y = cv_step(x, np.random.default_rng(0), 0.0)
    assert np.allclose(y, [1.5, 1, 5, 0.5, -1, 2])


def test_reflection_keeps_the_target_inside_and_flips_velocity():
    x = reflect(np.array([101.0, -2.0, 50, 3, -4, 1]), [0, 0, 0], [100, 100, 100])
    assert np.allclose(x, [99, 2, 50, -3, 4, 1])


def _run(scenario, steps):
    tgt = TruthTarget(target_params(scenario), np.random.default_rng(5))
    out = []
    for t in range(1, steps + 1):
        tgt.step(t)
        out.append((tgt.exists, tgt.detectable, None if tgt.position is None else tgt.position.copy()))
    return out


def test_scripted_existence_and_occlusions():
    s = load_scenario("paper-fig3", ["target.appears=3", "target.disappears=20"])
    out = _run(s, 25)
    exists = [e for e, _, _ in out]
    detect = [d for _, d, _ in out]
    assert exists == [3 <= t <= 20 for t in range(1, 26)]
    assert detect == [3 <= t <= 20 and not 14 <= t <= 17 for t in range(1, 26)]
    assert np.allclose(out[2][2], [20, 20, 20])  # first present step is the initial state


def test_target_stays_in_the_area_with_reflection():
    s = load_scenario("paper-fig3", ["steps=200", "target.accel_var=4"])
    for e, _, p in _run(s, 200):
        assert e and np.all(p >= 0) and np.all(p <= 100)


def test_target_that_leaves_disappears_with_walls_leave():
    s = load_scenario("paper-fig3", ["target.initial=[99, 50, 50, 5, 0, 0]", "target.walls=leave", "target.accel_var=0"])
    out = _run(s, 3)
    assert out[0][0] and not out[1][0] and not out[2][0]


def test_stochastic_existence_follows_survival_probability():
    s = load_scenario("paper-fig3", ["target.stochastic={birth_prob: 0.0, survival_prob: 0.9}", "target.occlusions=[]"])
    lifetimes = []
    for seed in range(400):
        tgt = TruthTarget(target_params(s), np.random.default_rng(seed))
        n = 0
        for t in range(1, 200):
            tgt.step(t)
            if not tgt.exists:
                break
            n += 1
        lifetimes.append(n)
    # geometric: present at step 1, then survives each step with p_s: mean 1 / (1 - p_s)
    assert np.mean(lifetimes) == pytest.approx(10.0, rel=0.12)


def test_jamming_response_lands_the_target_after_k_steps():
    s = load_scenario(
        "paper-fig3",
        ["target.response={threshold_db: -40, steps: 2, action: land, speed: 5}", "target.accel_var=0"],
    )
    tgt = TruthTarget(target_params(s), np.random.default_rng(0))
    tgt.step(1)
    tgt.apply_jamming(1, 1e-3)
    tgt.step(2)
    tgt.apply_jamming(2, 1e-5)  # below threshold: the count restarts
    tgt.step(3)
    tgt.apply_jamming(3, 1e-3)
    assert tgt.downed_at is None
    tgt.step(4)
    tgt.apply_jamming(4, 1e-3)
    assert tgt.downed_at == 4
    z = tgt.position[2]
    tgt.step(5)
    assert tgt.position[2] == pytest.approx(z - 5)
    for t in range(6, 20):
        tgt.step(t)
    assert tgt.position[2] == pytest.approx(0.0)


def test_gamma_of_eq_1_is_half_dt_squared_then_dt_by_hand():
    """Gamma pinned by hand, not by the library's own matrices: a Gamma of dt^2 would pass the
    covariance test above, which takes cv_matrices as its reference."""
    for dt in (1.0, 0.5, 2.0):
        Phi, Gamma = cv_matrices(dt)
        expected = np.zeros((6, 3))
        for k in range(3):
            expected[k, k] = dt * dt / 2
            expected[3 + k, k] = dt
        np.testing.assert_array_equal(Gamma, expected)
        # a constant acceleration a for one step moves x by a dt^2 / 2 and v by a dt
        x = Phi @ np.array([1.0, 2, 3, 0.5, 0, -1]) + Gamma @ np.array([2.0, 0, 0])
        assert x[0] == pytest.approx(1 + 0.5 * dt + dt * dt) and x[3] == pytest.approx(0.5 + 2 * dt)


def test_stochastic_existence_follows_the_bernoulli_transition_table():
    """Section IV-A's table: absent -> present with p_b, present -> present with p_s, counted over
    long chains (after the certain first appearance); a birth lands uniformly in the area."""
    s = load_scenario("paper-fig3", ["target.stochastic={birth_prob: 0.3, survival_prob: 0.8}", "target.occlusions=[]"])
    counts = np.zeros((2, 2))
    born_at = []
    for seed in range(20):
        tgt = TruthTarget(target_params(s), np.random.default_rng(seed))
        tgt.step(1)
        prev = tgt.exists
        for t in range(2, 500):
            tgt.step(t)
            counts[int(prev), int(tgt.exists)] += 1
            if tgt.exists and not prev:
                born_at.append(tgt.position.copy())
            prev = tgt.exists
    p_birth = counts[0, 1] / counts[0].sum()
    p_survive = counts[1, 1] / counts[1].sum()
    # about 4,000 absent and 6,000 present steps: standard errors near 0.007 and 0.005
    assert p_birth == pytest.approx(0.3, abs=0.035)
    assert p_survive == pytest.approx(0.8, abs=0.02)
    born_at = np.array(born_at)
    assert np.all((born_at >= 0) & (born_at <= 100))
    np.testing.assert_allclose(born_at.mean(axis=0), 50.0, atol=3.0)  # uniform: mean 50, standard error 28.9 / sqrt(~1,200)
