"""Pursuit beyond the paper: an aim ahead of x_bar (lead, intercept) and a searching team that keeps
the particles its own scans support."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.control.planning import planning_aim, search_point
from trackjam.control.pursuit import (AimSettings, aim_ahead, believers_state, intercept_steps, pursuit_aim,
                                     search_aim)
from trackjam.errors import ConfigError
from trackjam.estimation.bernoulli import Estimate
from trackjam.simulation.agent import Message
from trackjam.simulation.engine import Simulation

LOW, HIGH = np.zeros(3), np.full(3, 100.0)


def est(e, x, v):
    return Estimate(e, np.array([*x, *v], dtype=float), np.eye(6))


def test_the_papers_settings_give_planning_aim_bit_for_bit():
    rng = np.random.default_rng(0)
    predicted = [est(rng.uniform(), rng.uniform(0, 100, 3), rng.normal(0, 3, 3)) for _ in range(3)]
    got = pursuit_aim(predicted, rng.uniform(0, 100, (3, 3)), AimSettings(), LOW, HIGH)
    want = planning_aim(predicted)
    assert (got is None and want is None) or np.array_equal(got, want)
    assert pursuit_aim([est(0.4, [1, 2, 3], [1, 1, 1])], np.zeros((1, 3)), AimSettings(lead=0.5), LOW, HIGH) is None


def test_lead_aims_at_x_bar_plus_lead_times_v_bar():
    predicted = [est(0.9, [40, 50, 60], [2, 0, -1]), est(0.8, [42, 50, 58], [4, 2, -1]), est(0.2, [0, 0, 0], [9, 9, 9])]
    near = np.array([[41.0, 50.0, 59.0]])  # within one step: the intercept adds nothing
    aim = pursuit_aim(predicted, near, AimSettings(lead=0.5, horizon=4), LOW, HIGH)
    x_bar, v_bar = np.array([41.0, 50.0, 59.0]), np.array([3.0, 1.0, -1.0])
    assert np.allclose(aim, x_bar + 0.5 * v_bar)
    assert np.allclose(believers_state(predicted)[0], planning_aim(predicted))


@pytest.mark.parametrize("gap, speed, reach, horizon", [(12, 1, 5, 9), (12, 1, 5, 2), (3, 4, 5, 5), (30, 6, 5, 8)])
def test_intercept_is_the_first_step_the_nearest_agent_can_be_where_the_target_will_be(gap, speed, reach, horizon):
    x_bar, v_bar = np.array([gap, 0.0, 0.0]), np.array([speed, 0.0, 0.0])
    u = np.array([[0.0, 0.0, 0.0], [-50.0, 0.0, 0.0]])
    # the target flies straight away from the nearest agent: reachable at k when gap + (k-1) speed <= k reach
    brute = next((k for k in range(1, horizon + 1) if gap + (k - 1) * speed <= k * reach), horizon)
    assert intercept_steps(x_bar, v_bar, u, reach, horizon) == brute
    aim = aim_ahead(x_bar, v_bar, u, AimSettings(horizon=horizon, reach=reach))
    assert np.allclose(aim, x_bar + (brute - 1) * v_bar)


def test_intercept_aims_closer_to_where_a_fleeing_target_will_be_and_stays_in_the_area():
    x_bar, v_bar = np.array([50.0, 50.0, 50.0]), np.array([4.0, 0.0, 0.0])
    u = np.array([[30.0, 50.0, 50.0]])
    future = x_bar + 3 * v_bar
    ahead = aim_ahead(x_bar, v_bar, u, AimSettings(horizon=6))
    assert np.linalg.norm(ahead - future) < np.linalg.norm(x_bar - future)
    edge = [est(0.9, [98, 50, 50], [5, 0, 0])]
    assert pursuit_aim(edge, u, AimSettings(lead=2.0), LOW, HIGH)[0] == 100.0


def test_a_searching_team_moves_its_search_point_ahead_along_the_coasted_velocity():
    coasted = [np.array([40.0, 50, 50, 2, 0, 0]), np.array([42.0, 50, 50, 4, 0, 0])]
    predicted = [est(0.2, [0, 0, 0], [0, 0, 0])]
    aims, u = np.full((2, 3), 10.0), np.array([[41.0, 52.0, 50.0], [0.0, 0.0, 0.0]])
    point = search_point(coasted, predicted, aims, LOW, HIGH)
    assert np.array_equal(search_aim(coasted, predicted, aims, u, AimSettings(), LOW, HIGH), point)
    ahead = search_aim(coasted, predicted, aims, u, AimSettings(lead=0.5), LOW, HIGH)
    assert np.allclose(ahead, point + 0.5 * np.array([3.0, 0, 0]))
    never_tracked = search_aim([], predicted, aims, u, AimSettings(lead=0.5), LOW, HIGH)
    assert np.array_equal(never_tracked, search_point([], predicted, aims, LOW, HIGH))


@pytest.mark.parametrize("override, key", [("control.horizon=0", "control.horizon"), ("control.lead=-1", "control.lead"),
                                           ("fusion.search_reseed=never", "fusion.search_reseed"),
                                           ("control.close_in=0", "control.close_in"),
                                           ("control.close_in=-1", "control.close_in"),
                                           ("control.close_in=1.5", "control.close_in"),
                                           ("control.close_in=.nan", "control.close_in"),
                                           ("control.close_in=high", "control.close_in")])
def test_bad_pursuit_options_give_one_line_naming_the_key(override, key):
    with pytest.raises(ConfigError) as info:
        load_scenario("paper-fig3", [override])
    assert key in str(info.value) and "\n" not in str(info.value)


def _lost_team(reseed):
    s = load_scenario("paper-fig3", ["steps=3", "filter.particles=400", "filter.birth_particles=50",
                                     f"fusion.search_reseed={reseed}"])
    team = Simulation(s).team
    for a in team.agents:  # the team tracked a target at (50, 50, 50) two steps ago and lost it
        a.last_track, a.last_track_cov, a.steps_since_track = np.array([50.0, 50, 50, 1, 0, 0]), np.eye(6), 2
    team.predict(1)
    before = [a.filter.particles.copy() for a in team.agents]
    # agent 0's own scan raised its existence (0.2 -> 0.45); the others' lowered theirs
    posteriors = [
        Message(j, "posterior", 1, position=a.position, prior_existence=0.2,
                estimate=Estimate(0.45 if j == 0 else 0.1, np.array([10.0, 10, 10, 0, 0, 0]), np.eye(6)))
        for j, a in enumerate(team.agents)
    ]
    fused = team.fuse(posteriors)
    assert fused.mean is None  # nobody confirms: the team is searching
    return team, before


def test_a_searching_agent_whose_scan_carried_evidence_keeps_its_particles():
    team, before = _lost_team("evidence")
    assert np.array_equal(team.agents[0].filter.particles, before[0])
    coasted = np.array([53.0, 50, 50])  # last track coasted three steps, this one included
    for a, X in zip(team.agents[1:], before[1:]):
        assert not np.array_equal(a.filter.particles, X)
        assert np.linalg.norm(a.filter.particles[:, :3].mean(axis=0) - coasted) < 1.0


def test_always_reseeding_redraws_every_searching_agent_from_the_coasted_track():
    team, before = _lost_team("always")
    for a, X in zip(team.agents, before):
        assert not np.array_equal(a.filter.particles, X)


def test_the_pursuit_preset_is_paper_fig3_with_aim_pointing_and_the_options_that_held_best():
    a = load_scenario("pursuit").model_dump(exclude={"name"})
    b = load_scenario("paper-fig3").model_dump(exclude={"name"})
    diff = {(sec, k): a[sec][k] for sec in a if isinstance(a[sec], dict) for k in a[sec] if a[sec][k] != b[sec][k]}
    assert diff == {("antenna", "pointing"): "aim", ("control", "lead"): 0.5, ("control", "solver"): "exact",
                    ("filter", "visibility"): {"hide": 0.05, "reappear": 0.25, "per_particle": False},
                    ("fusion", "share"): "scans",
                    ("fusion", "report_spread"): 8.0, ("filter", "mode"): {"radius": 5.0, "mass": 0.2},
                    ("control", "plan_over"): "belief", ("control", "belief_spread"): 8.0,
                    ("filter", "cue"): {"existence": 0.9, "position_std": 2.0, "velocity_std": 2.0, "velocity": "target"},
                    # the exact search bounded by nodes, not wall time: runs repeat under any load
                    ("control", "node_limit"): 2_000_000, ("control", "time_limit_s"): 3600.0}



def test_a_team_with_a_lead_plans_and_points_half_a_step_ahead_of_the_papers_x_bar():
    fast = ["steps=3", "filter.particles=500", "filter.birth_particles=100", "control.solver=exact",
            "antenna.pointing=aim"]
    paper = Simulation(load_scenario("paper-fig3", fast))
    ahead = Simulation(load_scenario("paper-fig3", fast + ["control.lead=0.5"]))
    x_bar = paper.step().step["aim"]
    rec = ahead.step()
    v_bar = np.mean([m.estimate.mean[3:] for m in ahead.team.fresh(0) if m.estimate.existence > 0.5], axis=0)
    assert np.linalg.norm(v_bar) > 0.0
    assert np.allclose(rec.step["aim"], x_bar + 0.5 * v_bar)
    assert np.allclose(rec.agents["point"], rec.step["aim"])  # pointing: aim steers every antenna there


@pytest.mark.parametrize("override, why", [("control.solver=greedy", "control.solver `greedy`"),
                                           ("control.constraints=false", "control.constraints `false`")])
def test_closing_in_is_refused_where_the_plan_ignores_eq_13_already(override, why):
    with pytest.raises(ConfigError) as info:
        load_scenario("paper-fig3", ["control.close_in=0.05", override])
    line = str(info.value)
    assert "\n" not in line and line.startswith("--set control.close_in=0.05: control.close_in (0.05): " + why)
