"""The step-wise engine: reset and step, external actions, and the message rounds of a step."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.simulation.engine import Simulation
from trackjam.simulation.loop import simulate
from trackjam.simulation.team import Exchange

FAST = ["control.solver=exact", "steps=4", "filter.particles=500", "filter.birth_particles=100"]


def test_stepping_by_hand_equals_simulate():
    s = load_scenario("paper-fig3", FAST)
    sim = Simulation(s)
    records = [sim.step() for _ in range(s.steps)]
    whole = simulate(s)
    assert [r.t for r in records] == [1, 2, 3, 4]
    assert np.array_equal(sim.result().agents["x"], whole.agents["x"])
    assert np.array_equal(sim.result().steps["existence"], whole.steps["existence"])


def test_reset_replays_the_same_run():
    sim = Simulation(load_scenario("paper-fig3", FAST))
    first = [sim.step().step["existence"] for _ in range(4)]
    sim.reset()
    assert sim.t == 0
    assert [sim.step().step["existence"] for _ in range(4)] == first


def test_given_actions_are_applied_and_logged():
    s = load_scenario("paper-fig3", FAST)
    sim = Simulation(s)
    moves, levels = np.array([0, 5, 10]), np.array([1, 2, 3])
    rec = sim.step((moves, levels))
    assert rec.step["mode"] == "external"
    D = sim.c.displacements
    assert np.allclose(rec.agents["pos"] - rec.agents["prev"], D[moves])
    assert np.array_equal(rec.agents["level_index"], levels)
    assert np.allclose(rec.agents["power_w"], sim.c.antenna.levels_w[levels])


def test_each_record_carries_the_teams_fused_estimate_reported_or_not():
    """record.fused is the team's estimate; the report (step["estimate"]) is its position while
    P(exists and visible) > 0.5 and its spread is within fusion.report_spread, else None."""
    from trackjam.control.planning import position_spread
    from trackjam.simulation.engine import seen

    s = load_scenario("pursuit", ["steps=20", "filter.particles=800", "filter.birth_particles=200", "seed=3"])
    sim = Simulation(s)
    reported = silent = 0
    while not sim.done:
        rec = sim.step()
        fused, est = rec.fused, rec.step["estimate"]
        assert fused is not None and fused.existence == rec.step["existence"]
        if seen(fused) > 0.5 and position_spread(fused.cov) <= s.fusion.report_spread:
            assert np.array_equal(est, fused.mean[:3])
            reported += 1
        else:
            assert est is None
            silent += 1
    assert reported and silent  # both branches were met (the occlusion silences the team)


def test_step_after_the_end_is_refused():
    sim = Simulation(load_scenario("paper-fig3", FAST))
    for _ in range(4):
        sim.step()
    assert sim.done
    with pytest.raises(RuntimeError, match="ended"):
        sim.step()


def test_every_step_has_prediction_plan_and_posterior_rounds(monkeypatch):
    kinds = []
    original = Exchange.send

    def spy(self, t, kind, messages):
        kinds.append((t, kind, len(messages)))
        return original(self, t, kind, messages)

    monkeypatch.setattr(Exchange, "send", spy)
    simulate(load_scenario("paper-fig3", FAST[:2] + ["steps=3"]))
    assert kinds == [(t, k, 3) for t in (1, 2, 3) for k in ("prediction", "plan", "posterior")]
