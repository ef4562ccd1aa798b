"""Where an agent plans: the belief sample it sends, and the team's pooled planning sample."""

import numpy as np

from trackjam.config import load_scenario
from trackjam.control.planning import belief_sample, pooled_belief, position_spread, wide_belief
from trackjam.estimation.bernoulli import Estimate
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


def test_the_position_spread_is_the_root_mean_square_of_the_axis_deviations():
    cov = np.diag([1.0, 4.0, 16.0, 100.0, 100.0, 100.0])  # velocity variances play no part
    assert position_spread(cov) == np.sqrt(21.0 / 3.0)


def test_a_belief_is_wide_when_some_prediction_heard_spreads_beyond_the_bound():
    tight = Estimate(0.9, np.zeros(6), np.eye(6))  # spread 1 m
    wide = Estimate(0.2, np.zeros(6), 16.0 * np.eye(6))  # spread 4 m, whatever its existence
    assert wide_belief([tight], None) and wide_belief([], None)  # no bound: always the belief
    assert not wide_belief([tight], 1.0)  # at the bound: not above it
    assert wide_belief([tight], 0.999)
    assert wide_belief([tight, wide], 3.0) and not wide_belief([tight, wide], 4.0)
    assert not wide_belief([], 3.0)


COMMON = ["control.solver=exact", "steps=8", "filter.particles=500", "filter.birth_particles=100",
          "antenna.pointing=aim", "control.plan_over=belief", "control.belief_samples=8"]


def _columns(r):
    return {k: v for k, v in {**r.steps, **{f"agent_{k}": v for k, v in r.agents.items()}}.items()
            if k not in ("solve_s", "step_s")}


def _same(a, b):
    ca, cb = _columns(a), _columns(b)
    return all(np.array_equal(ca[k], cb[k], equal_nan=ca[k].dtype.kind == "f") for k in ca)


def test_a_bound_no_belief_reaches_is_the_point_and_a_bound_every_belief_passes_is_the_belief():
    """control.belief_spread: the belief samples need no random draw, so the switch changes
    nothing but the objective; above every spread the run is plan_over: point's, bit for bit,
    and below every spread plan_over: belief's."""
    point = simulate(load_scenario("paper-fig3", COMMON[:5]))
    belief = simulate(load_scenario("paper-fig3", COMMON))
    assert not _same(point, belief)
    assert _same(simulate(load_scenario("paper-fig3", COMMON + ["control.belief_spread=100000"])), point)
    assert _same(simulate(load_scenario("paper-fig3", COMMON + ["control.belief_spread=0.001"])), belief)


def test_the_team_plans_over_the_belief_exactly_on_the_steps_whose_predictions_spread_beyond_the_bound(monkeypatch):
    import trackjam.simulation.team as team_module

    calls = []
    build = team_module.build_problem

    def spy(positions, aim, *args, **kwargs):
        calls.append(args[-2] is not None if len(args) >= 8 else kwargs.get("samples") is not None)
        return build(positions, aim, *args, **kwargs)

    decide = team_module.Team._proposals
    spreads = []

    def proposals(self, working, *args, **kwargs):
        spreads.append(max(position_spread(m.estimate.cov) for m in self.fresh(working[0])))
        return decide(self, working, *args, **kwargs)

    monkeypatch.setattr(team_module, "build_problem", spy)
    monkeypatch.setattr(team_module.Team, "_proposals", proposals)
    bound = 8.0
    simulate(load_scenario("paper-fig3", COMMON + ["steps=12", "target.occlusions=[[4, 9]]",
                                                   f"control.belief_spread={bound}"]))
    assert len(calls) == len(spreads) == 12  # every agent holds the same problem: one search per step
    assert calls == [s > bound for s in spreads]
    assert any(calls) and not all(calls)


def test_a_belief_spread_without_planning_over_the_belief_warns_under_its_key():
    from trackjam.config.warnings import scenario_warnings

    lines = scenario_warnings(load_scenario("paper-fig3", ["control.belief_spread=8"]))
    assert lines == ["control.belief_spread: 8 m has no effect under control.plan_over: point "
                     "(it bounds plan_over: belief)"]
    assert scenario_warnings(load_scenario("pursuit")) == []


def test_the_belief_steps_take_their_own_n_and_the_point_steps_keep_at_least(monkeypatch):
    """control.belief_at_least: Eq. (12)'s n on the steps planned over the belief; the others keep
    control.at_least."""
    import trackjam.simulation.team as team_module

    calls = []
    build = team_module.build_problem

    def spy(positions, aim, displacements, ant, low, high, n, constraints, samples=None, weights=None):
        calls.append((samples is not None, n))
        return build(positions, aim, displacements, ant, low, high, n, constraints, samples, weights)

    monkeypatch.setattr(team_module, "build_problem", spy)
    simulate(load_scenario("paper-fig3", COMMON + ["steps=12", "target.occlusions=[[4, 9]]",
                                                   "control.belief_spread=8", "control.belief_at_least=1"]))
    assert {wide for wide, _ in calls} == {True, False}
    assert all(n == (1 if wide else 2) for wide, n in calls)


def test_a_belief_at_least_equal_to_at_least_changes_nothing_and_null_is_at_least():
    items = COMMON + ["steps=10", "target.occlusions=[[4, 7]]", "control.belief_spread=8"]
    runs = [simulate(load_scenario("paper-fig3", items + extra)).agents
            for extra in ([], ["control.belief_at_least=2"], ["control.belief_at_least=1"])]
    assert all(np.array_equal(runs[0][k], runs[1][k]) for k in runs[0])
    assert not np.array_equal(runs[0]["x"], runs[2]["x"])  # the wide steps planned for any detection


def test_a_belief_at_least_is_checked_against_the_team_and_warns_without_the_belief():
    import pytest

    from trackjam.config.warnings import scenario_warnings
    from trackjam.errors import ConfigError

    with pytest.raises(ConfigError, match=r"control.belief_at_least \(4\) exceeds the number of agents in agents.initial \(3\)"):
        load_scenario("pursuit", ["control.belief_at_least=4"])
    with pytest.raises(ConfigError, match="control.belief_at_least"):
        load_scenario("pursuit", ["control.belief_at_least=0"])
    lines = scenario_warnings(load_scenario("paper-fig3", ["control.belief_at_least=1"]))
    assert lines == ["control.belief_at_least: 1 has no effect under control.plan_over: point "
                     "(it is the n of the steps planned over the belief)"]
