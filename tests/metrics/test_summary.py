"""A run's summary carries the track quality judged by the truth and the clairvoyant ceiling,
and its steps log the per-step class: all three agree with the pure functions on a real run."""

import math

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.metrics.ceiling import clairvoyant_ceiling
from trackjam.metrics.track_quality import CLASSES, step_classes, track_quality
from trackjam.simulation.loop import simulate

# a short Fig. 3 run hidden for two steps, so every class and a re-acquisition can occur
SHORT = ["steps=10", "control.solver=exact", "filter.particles=1000", "filter.birth_particles=300",
         "target.occlusions=[[4, 5]]"]


@pytest.fixture(scope="module", params=[5.0, 0.4])
def run(request):
    s = load_scenario("paper-fig3", SHORT + [f"metrics.gate={request.param}"])
    return s, simulate(s)


def test_the_steps_log_classes_every_step_as_step_classes_does(run):
    s, r = run
    expected = np.asarray(CLASSES)[step_classes(r.steps, s.metrics.gate)]
    assert r.steps["quality"].tolist() == expected.tolist()
    # columns stay in log order: the class follows the OSPA it refines
    names = list(r.steps)
    assert names.index("quality") == names.index("ospa") + 1
    # the occluded steps are never held, false or missed
    hidden = r.steps["quality"][3:5]
    assert set(hidden) <= {"phantom", "silent"}


def test_the_summary_holds_track_quality_and_the_ceiling_of_its_own_truth(run):
    s, r = run
    q = track_quality(r.steps, s.metrics.gate)
    assert {k: r.summary[k] for k in q} == q
    truth = np.stack([r.steps[f"truth_{a}"] for a in "xyz"], axis=1)
    ceiling = clairvoyant_ceiling(truth, r.steps["target_detectable"], s.agents.initial,
                                  max(s.agents.radial_steps), s.area.low, s.area.high)
    assert r.summary["ceiling_share"] == ceiling.share and r.summary["ceiling_d_m"] == 8.0
    counts = {c: int(np.sum(r.steps["quality"] == c)) for c in CLASSES}
    assert r.summary["held_steps"] == counts["held"]
    assert r.summary["detectable_steps"] == counts["held"] + counts["false_track"] + counts["missed"] == 8
    # a confirmed report is either on the target, off it, or about a hidden target
    assert r.summary["confirmed_steps"] == counts["held"] + counts["false_track"] + counts["phantom"]


def test_a_tighter_gate_never_holds_more():
    s = load_scenario("paper-fig3", SHORT)
    r = simulate(s)
    wide, tight = track_quality(r.steps, 5.0), track_quality(r.steps, 0.4)
    assert tight["held_steps"] <= wide["held_steps"]
    assert tight["held_steps"] + tight["false_track_steps"] == wide["held_steps"] + wide["false_track_steps"]


def test_confirmed_steps_count_the_reports_not_the_existence_alone():
    """Under the report rule of `pursuit` (P(exists and visible) > 0.5, a spread within 8 m) the
    team can believe in the target (existence > 0.5) yet report nothing: such a step is missed
    or silent, and confirmed_steps (it had counted existence > 0.5) does not count it."""
    s = load_scenario("pursuit", ["steps=30", "filter.particles=2000", "filter.birth_particles=500"])
    r = simulate(s)
    counts = {c: int(np.sum(r.steps["quality"] == c)) for c in CLASSES}
    believed = int(np.sum(r.steps["existence"] > 0.5))
    assert r.summary["confirmed_steps"] == counts["held"] + counts["false_track"] + counts["phantom"]
    assert r.summary["confirmed_steps"] < believed  # this run has withheld reports: the test can tell


def test_the_summarys_figures_are_the_means_and_counts_of_its_own_logs():
    """Fig. 4's figures (jamming incidents per agent, the powers, OSPA) from the logs by hand,
    row by row with each row's agent id (not the reshape summarise uses). A run with Eq. (13)
    off, so that agents are jammed several steps each and the powers vary from step to step:
    under the constraints no agent is ever jammed, and counting "jammed at least once" instead
    of the jammed steps, a maximum for the mean interference, or a median for the mean target
    power passed every test."""
    s = load_scenario("paper-fig3", SHORT + ["control.constraints=false"])
    r = simulate(s)
    a, st = r.agents, r.steps
    n = len(s.agents.initial)
    jammed_steps = [0] * n
    for agent, jammed in zip(a["agent"].tolist(), a["jammed"].tolist()):
        jammed_steps[agent] += bool(jammed)
    assert r.summary["jamming_incidents"] == jammed_steps
    assert max(jammed_steps) >= 2  # the case tells a count of steps from "ever jammed"
    assert r.summary["jamming_incidents_per_agent"] == pytest.approx(sum(jammed_steps) / n, rel=1e-12)
    # an agent is jammed when it receives at least the interference limit (Eq. 13)
    limit = 10 ** (s.antenna.interference_limit_db / 10)
    assert a["jammed"].tolist() == [bool(w >= limit) for w in a["interference_w"].tolist()]

    def mean(values):
        values = [float(v) for v in values]
        return math.fsum(values) / len(values)

    assert len(set(a["interference_w"].tolist())) > 2 and len(set(st["target_received_w"].tolist())) > 2
    assert r.summary["agent_received_w_mean"] == pytest.approx(mean(a["interference_w"]), rel=1e-12)
    assert r.summary["transmit_w_mean"] == pytest.approx(mean(a["power_w"]), rel=1e-12)
    assert r.summary["target_received_w_mean"] == pytest.approx(mean(st["target_received_w"]), rel=1e-12)
    assert r.summary["ospa_mean"] == pytest.approx(mean(st["ospa"]), rel=1e-12)
    # the power at the target is the sum over the agents of what each delivers to it
    for t, total in zip(st["t"].tolist(), st["target_received_w"].tolist()):
        mine = [w for tt, w in zip(a["t"].tolist(), a["to_target_w"].tolist()) if tt == t]
        assert len(mine) == n and total == pytest.approx(math.fsum(mine), rel=1e-12, abs=1e-300)
