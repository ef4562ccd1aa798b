"""The diagnostic oracles (``oracle.*``): each tells the team what it says, when it says, and
nothing else; off, they change nothing."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.simulation.build import check_swarm_options
from trackjam.simulation.engine import Simulation
from trackjam.simulation.loop import simulate

# the preset with small filters, and a short occlusion early on (steps 4-5)
FAST = ["steps=10", "filter.particles=800", "filter.birth_particles=200", "target.occlusions=[[4, 5]]"]


def scenario(*extra: str, seed: int = 3):
    return load_scenario("pursuit", [*FAST, f"seed={seed}", *extra])


def told_steps(result) -> set[int]:
    """The steps whose logged aim is the target's true position, to the bit."""
    s = result.steps
    return {int(t) for t, a, x in zip(s["t"], np.c_[s["aim_x"], s["aim_y"], s["aim_z"]],
                                      np.c_[s["truth_x"], s["truth_y"], s["truth_z"]]) if np.array_equal(a, x)}


def test_oracles_off_change_nothing():
    plain = simulate(scenario())
    off = simulate(scenario("oracle={}"))
    assert off.scenario.oracle is not None and plain.scenario.oracle is None
    for key in plain.steps:
        if key not in ("solve_s", "step_s"):  # wall times
            a, b = plain.steps[key], off.steps[key]
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), key
    assert np.array_equal(plain.agents["existence"], off.agents["existence"], equal_nan=True)


def test_state_before_hiding_redraws_every_filter_tight_around_the_truth():
    sim = Simulation(scenario("oracle.state_before_hiding=true"))
    plain = Simulation(scenario())
    for _ in range(3):  # step 3 is the last before the occlusion of steps 4-5
        sim.step()
        plain.step()
    x = sim.truth.state
    assert np.array_equal(x, plain.truth.state)  # the truth is not touched
    for a, b in zip(sim.team.agents, plain.team.agents):
        X = a.filter.particles
        assert np.allclose(X.mean(axis=0), x, atol=[0.05] * 3 + [0.02] * 3)
        assert np.allclose(X.std(axis=0), [0.3] * 3 + [0.1] * 3, rtol=0.1)
        assert a.filter.e == pytest.approx(b.filter.e)  # its existence is kept
        assert np.abs(b.filter.particles.mean(axis=0) - x).max() > 0.05  # the team alone knows less


def weighted_moments(f):
    X, log_w = f.particles, f.log_w
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    mean = w @ X
    return mean, np.sqrt(w @ (X - mean) ** 2)


def test_mean_before_hiding_moves_every_belief_onto_the_truth_keeping_its_spread():
    sim = Simulation(scenario("oracle.mean_before_hiding=true"))
    plain = Simulation(scenario())
    for _ in range(3):
        sim.step()
        plain.step()
    x = sim.truth.state
    for a, b in zip(sim.team.agents, plain.team.agents):
        mean, spread = weighted_moments(a.filter)
        plain_mean, plain_spread = weighted_moments(b.filter)
        assert np.allclose(mean, x, atol=1e-9)
        assert np.allclose(spread, plain_spread, rtol=1e-9)  # the same belief, centred elsewhere
        assert np.abs(plain_mean - x).max() > 0.05
        # the estimate (at the mode, in the preset) moves by the same offset; the existence stays
        assert np.allclose(a.filter.estimate().mean - b.filter.estimate().mean, x - plain_mean, atol=1e-9)
        assert a.filter.e == b.filter.e


@pytest.mark.parametrize("k", [1, 3])
def test_truth_after_hiding_tells_the_first_k_steps_after_the_occlusion(k):
    result = simulate(scenario(f"oracle.truth_after_hiding={k}"))
    assert told_steps(result) == set(range(6, 6 + k))
    assert set(result.steps["mode"][5:5 + k]) == {"track"}  # planned at the point, as a located target


@pytest.mark.parametrize("k", [1, 2])
def test_point_after_hiding_points_every_antenna_at_the_truth_on_the_first_k_steps(k):
    told, plain = simulate(scenario(f"oracle.point_after_hiding={k}")), simulate(scenario())
    a, s = told.agents, told.steps
    truth = {int(t): np.array([x, y, z]) for t, x, y, z in zip(s["t"], s["truth_x"], s["truth_y"], s["truth_z"])}
    pointed = {int(t) for t in set(a["t"].tolist())
               if all(np.array_equal(p, truth[int(t)])
                      for p in np.c_[a["point_x"], a["point_y"], a["point_z"]][a["t"] == t])}
    assert pointed == set(range(6, 6 + k))
    before = a["t"] <= 5  # the same run until the occlusion ends: the plans are not told anything
    assert np.array_equal(a["x"][before], plain.agents["x"][before])
    assert told_steps(told) == set()


def test_follow_up_tells_the_steps_after_each_detection_after_the_occlusion():
    followed = 0
    for seed in (1, 2, 3, 4, 5, 6):
        result = simulate(scenario("oracle.follow_up=2", seed=seed))
        a = result.agents
        detected = {int(t) for t, d in zip(a["t"], a["detected"]) if d and t > 5}
        expected = {t + i for t in detected for i in (1, 2) if t + i <= 10}
        assert told_steps(result) == expected
        followed += bool(expected)
    assert followed >= 2, "too few seeds with a detection after the occlusion to follow up"


def test_empty_hidden_scans_makes_the_occluded_scans_carry_no_evidence():
    told = Simulation(scenario("oracle.empty_hidden_scans=true"))
    plain = Simulation(scenario())
    for t in range(1, 8):
        told.step()
        plain.step()
        ev_told = [a.filter.log_evidence for a in told.team.agents]
        ev_plain = [a.filter.log_evidence for a in plain.team.agents]
        if t in (4, 5):  # every antenna weighed as off: L_i = 1 for every particle
            assert ev_told == pytest.approx([0.0] * 3, abs=1e-9)
            assert all(abs(e) > 1e-6 for e in ev_plain)
        else:
            assert all(abs(e) > 1e-6 for e in ev_told)
    # the sensors still saw what they saw: the scans of the first occluded step are the same
    m_told, m_plain = told.result().measurements, plain.result().measurements
    first = [i for i, t in enumerate(m_plain["t"]) if t <= 4]
    assert np.array_equal(m_told["rho"][first], m_plain["rho"][first])


def test_the_swarm_engine_refuses_the_oracles():
    s = load_scenario("swarm-3", ["oracle.follow_up=2"])
    with pytest.raises(ConfigError, match="oracle"):
        check_swarm_options(s)
