"""The experiments of Section VI: Table I's 8 configurations, constraints on/off, and the
solver comparison, all on the paper's settings without Fig. 3's occlusions."""

from __future__ import annotations

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.experiments.definitions import (
    COMMS_VARIANTS,
    DRAW,
    EXPERIMENTS,
    HOLDING_VARIANTS,
    SEED,
    base_data,
    configuration_columns,
    draw_for,
    get_experiment,
    trial_scenario,
)


def _scenarios(name, k=0, seed=0, overrides=(), steps=30):
    e = get_experiment(name)
    base = base_data(e, steps=steps, overrides=list(overrides))
    d = draw_for(base, seed, k)
    return [trial_scenario(e, base, c, d, seed) for c in e.configurations]


def test_table1_is_11_or_79_controls_times_four_opening_angles():
    cols = [configuration_columns(s) for s in _scenarios("table1")]
    assert [c["n_controls"] for c in cols] == [11] * 4 + [79] * 4
    assert [c["opening_angle_deg"] for c in cols] == [60, 80, 100, 120] * 2
    assert all(c["constraints"] and c["solver"] == "grasp" for c in cols)


def test_constraints_and_solvers_compare_one_setting_each():
    assert [configuration_columns(s)["constraints"] for s in _scenarios("constraints")] == [True, False]
    assert [configuration_columns(s)["solver"] for s in _scenarios("solvers")] == ["grasp", "exact"]


@pytest.mark.parametrize("name", [n for n, e in EXPERIMENTS.items() if e.trials == DRAW])
def test_every_configuration_sees_the_same_trial(name):
    ss = _scenarios(name, k=4, seed=9)
    for s in ss[1:]:
        assert s.target.initial == ss[0].target.initial
        assert s.agents.initial == ss[0].agents.initial
        assert s.agents.initial_aim == tuple(ss[0].target.initial[:3])
    assert len({s.seed for s in ss}) == 1  # and the same random streams (common random numbers)
    assert len({s.seed for s in _scenarios(name, k=5, seed=9)} | {ss[0].seed}) == 2  # another trial: others


@pytest.mark.parametrize("name", ["table1", "constraints"])
def test_every_configuration_of_a_trial_faces_the_same_truth(name):
    """Common random numbers: the truth's random walk of trial k does not depend on the
    configuration (the target does not answer jamming here), so the comparison is paired on it."""
    from trackjam.simulation.loop import simulate

    paths = []
    for s in _scenarios(name, k=2, seed=3, steps=6, overrides=["filter.particles=300", "filter.birth_particles=60",
                                                               "control.solver=exact"]):
        steps = simulate(s).steps
        paths.append(np.stack([steps["truth_x"], steps["truth_y"], steps["truth_z"]], axis=1))
    for path in paths[1:]:
        np.testing.assert_array_equal(path, paths[0])


def _pairs(name):
    return {label: (a, b) for a, b, label in get_experiment(name).pairs}


def test_the_paired_comparisons_are_the_papers_questions():
    t1 = _pairs("table1")
    assert t1["80 deg: 11 -> 79 controls"] == (2, 6) and t1["120 deg: 11 -> 79 controls"] == (4, 8)
    assert t1["11 controls: 60 -> 80 deg"] == (1, 2) and t1["79 controls: 100 -> 120 deg"] == (7, 8)
    assert t1["11 controls: 60 -> 120 deg"] == (1, 4) and t1["79 controls: 60 -> 120 deg"] == (5, 8)
    assert len(t1) == 4 + 2 * 4
    assert _pairs("constraints") == {"constraints on -> off": (1, 2)}
    assert _pairs("solvers") == {"grasp -> exact": (1, 2)}
    holding, n = _pairs("holding"), len(HOLDING_VARIANTS)
    assert holding["paper, pointing: aim -> preset pursuit"] == (2, n)
    assert holding["paper, pointing: aim -> paper, pointing: truth"] == (2, 1)
    assert holding["paper, pointing: truth -> preset pursuit"] == (1, n) and len(holding) == n
    comms = _pairs("comms")
    assert comms["loss 0 -> agent 0 breaks down at step 10"] == (1, len(COMMS_VARIANTS))
    assert len(comms) == len(COMMS_VARIANTS) - 1
    for name, e in EXPERIMENTS.items():  # every pair names two of the experiment's configurations
        indices = {c.index for c in e.configurations}
        assert all(a in indices and b in indices and a != b for a, b, _ in e.pairs), name


def test_the_base_is_the_papers_settings_without_occlusions():
    s = _scenarios("constraints")[0]
    assert s.target.occlusions == [] and s.target.appears == 1 and s.target.disappears is None
    assert s.steps == 30 and s.n_agents == 3
    assert s.antenna.opening_angle_deg == 80 and s.control.grasp.samples == 10000
    np.testing.assert_allclose(s.antenna.levels_w[-1], 10**0.05)


def test_user_overrides_reach_every_configuration():
    ss = _scenarios("table1", overrides=["control.solver=exact", "filter.particles=200"])
    assert all(s.control.solver == "exact" and s.filter.particles == 200 for s in ss)


@pytest.mark.parametrize(
    "override, words",
    [
        ("antenna.opening_angle_deg=90", "swept"),
        ("antenna={height: 30}", "swept"),
        ("agents=null", "every trial"),
        ("steps=5", "--steps"),
        ("seed=5", "--seed"),
        ("target.initial=[1,2,3,0,0,0]", "every trial"),
        ("filter.particles=-3", "filter.particles"),
        ("control.nope=1", "unknown key"),
    ],
)
def test_bad_overrides_are_one_line_config_errors(override, words):
    with pytest.raises(ConfigError, match=words.replace(".", r"\.").replace("-", r"\-")) as err:
        _scenarios("table1", overrides=[override])
    assert "\n" not in str(err.value)


def test_unknown_experiment_names_the_choices():
    with pytest.raises(ConfigError, match="table1, constraints, solvers"):
        get_experiment("table2")


@pytest.mark.parametrize("name", [n for n, e in EXPERIMENTS.items() if e.trials == SEED])
def test_seed_experiments_run_fig3_itself_with_one_truth_per_trial(name):
    """Every configuration of trial k shares Fig. 3's start and occlusion and trial k's seed (the
    same truth, paired); another trial has another seed."""
    fig3 = load_scenario("paper-fig3")
    trial0, trial1 = _scenarios(name, k=0, seed=9), _scenarios(name, k=1, seed=9)
    for s in trial0 + trial1:
        assert s.target.initial == fig3.target.initial and s.agents.initial == fig3.agents.initial
        assert s.target.occlusions == fig3.target.occlusions and s.control.solver == "exact"
    assert len({s.seed for s in trial0}) == 1 and len({s.seed for s in trial1}) == 1
    assert trial0[0].seed != trial1[0].seed


def test_holding_compares_the_papers_pointing_with_each_option():
    ss = _scenarios("holding")
    assert [c.label for c in get_experiment("holding").configurations] == [label for label, _ in HOLDING_VARIANTS]
    assert [s.antenna.pointing for s in ss[:2]] == ["truth", "aim"]
    assert all(s.antenna.pointing == "aim" for s in ss[2:])
    assert [s.control.plan_over for s in ss] == ["point"] * 3 + ["belief"] + ["point"] * 9 + ["belief", "point", "belief"]
    assert [s.control.belief_spread for s in ss] == [None] * 13 + [8.0, None, 8.0]  # row 14 alone, row 15, the preset
    assert [s.control.close_in for s in ss] == [None] * 14 + [0.05, None]  # row 15 alone; the preset keeps it off
    assert [s.control.lead for s in ss][4] == 0.5 and ss[5].control.horizon == 5
    assert [s.fusion.share for s in ss[7:11]] == ["scans", "posteriors", "posteriors", "scans"]
    assert [s.filter.visibility is not None for s in ss[7:11]] == [False, True, False, True]
    assert ss[9].fusion.report_spread == 8.0


def test_comms_sweeps_loss_delay_and_failures_with_aimed_antennas():
    ss = _scenarios("comms")
    assert len(ss) == len(COMMS_VARIANTS)
    assert [s.comms.loss for s in ss[:5]] == [0.0, 0.1, 0.3, 0.5, 1.0]
    assert ss[5].comms.delay_steps == 1 and ss[5].comms.loss == 0 and ss[5].comms.stale == "coast"
    assert ss[6].comms.delay_steps == 1 and ss[6].comms.stale == "drop"
    assert [(f.agent, f.step, f.mode) for f in ss[7].comms.failures] == [(0, 10, "publisher")]
    assert [(f.agent, f.step, f.mode) for f in ss[8].comms.failures] == [(0, 10, "breakdown")]
    assert all(s.antenna.pointing == "aim" and s.control.solver == "exact" for s in ss)


def test_seed_experiments_let_the_user_move_the_occlusion_but_not_the_sweep():
    ss = _scenarios("holding", overrides=["target.occlusions=[[3, 4]]"])
    assert all([list(o) for o in s.target.occlusions] == [[3, 4]] for s in ss)
    with pytest.raises(ConfigError, match="swept by experiment holding"):
        _scenarios("holding", overrides=["antenna.pointing=aim"])
    with pytest.raises(ConfigError, match="--seed"):
        _scenarios("comms", overrides=["seed=4"])


@pytest.mark.parametrize("key, words", [
    ("steps", "set by every trial of an experiment"), ("antenna.pointing", "swept by experiment holding"),
    ("targets", "draws one target per trial"),
])
def test_a_long_key_the_experiment_owns_is_shortened_in_the_message(key, words):
    # "--set steps.kkk...: set by every trial" echoed the whole key (100 kB)
    with pytest.raises(ConfigError) as err:
        _scenarios("holding", overrides=[f"{key}.{'k' * 100_000}=1"])
    assert words in str(err.value) and len(str(err.value)) < 200


def test_the_preset_row_of_holding_is_the_preset_itself():
    row = next(c for c in get_experiment("holding").configurations if c.label == "preset pursuit")
    s = _scenarios("holding")[row.index - 1]
    preset = load_scenario("pursuit")
    for section in ("target", "agents", "antenna", "sensor", "filter", "fusion", "comms", "metrics"):
        assert getattr(s, section) == getattr(preset, section), section
    mine, theirs = s.control.model_dump(), preset.control.model_dump()
    mine["grasp"].pop("threads"), theirs["grasp"].pop("threads")  # experiments run one thread per trial
    assert mine == theirs


@pytest.mark.parametrize("name", ["table1", "swarm"])
def test_an_area_without_the_presets_start_is_taken_where_the_trials_place_their_own(name):
    # Fig. 3's agents at 30-40 m lay outside --set area.high=[25,25,25]: every drawing experiment
    # refused the area, and --set agents.initial, which every trial sets, was refused too
    from trackjam.experiments.engine import _plan

    overrides = ["area.high=[25,25,25]"]
    scenarios, _ = _plan(get_experiment(name), 1, 2, 0, overrides)
    assert scenarios
    for s in scenarios.values():
        assert np.all(np.array(s.agents.initial, dtype=float) <= 25.0)


def test_an_experiment_on_fig3s_start_still_refuses_an_area_without_it():
    from trackjam.experiments.engine import _plan

    with pytest.raises(ConfigError, match=r"--set area.high=\[25,25,25\]: agents.initial\[0\]"):
        _plan(get_experiment("holding"), 1, 2, 0, ["area.high=[25,25,25]"])


@pytest.mark.parametrize("changed, words", [
    ({"configurations": ()}, "configurations must be a non-empty tuple"),
    ({"configurations": "dup"}, "configuration indices must be distinct whole numbers >= 1, got [1, 1]"),
    ({"configurations": "zero"}, "configuration indices must be distinct whole numbers >= 1, got [0]"),
    ({"figure": "../../escape.png"}, "figure must be a file name in --out"),  # it was written outside --out
    ({"figure": "fig"}, "figure must be a file name in --out"),  # matplotlib failed once every trial had run
    ({"figure": "summary.csv"}, "figure must be a file name in --out"),
    ({"trials": "bogus"}, "trials must be one of"),
    ({"pairs": ((1, 7, "x"),)}, "pairs [(1, 7, 'x')] name configurations it does not have"),
    ({"trial": 5}, "trial must be a function of a scenario"),
])
def test_a_hand_built_experiment_is_checked_when_it_is_made(changed, words):
    # two configurations of one index shared one trial file and one summary row, silently
    from trackjam.experiments.experiment import Configuration, Experiment

    configurations = {"dup": (Configuration(1, "a", {"antenna.opening_angle_deg": 60}),
                              Configuration(1, "b", {"antenna.opening_angle_deg": 120})),
                      "zero": (Configuration(0, "a"),)}
    fields = dict(name="mine", description="", configurations=(Configuration(1, "a"), Configuration(2, "b")),
                  figure="mine.png") | changed
    if isinstance(fields["configurations"], str):
        fields["configurations"] = configurations[fields["configurations"]]
    with pytest.raises(ValueError) as err:
        Experiment(**fields)
    assert words in str(err.value)


@pytest.mark.parametrize("settings", [{"steps": 3}, {"seed": 3}, {"agents.initial": [[1.0, 1.0, 1.0]]}])
def test_a_configuration_may_not_set_what_every_trial_sets(settings):
    # {"steps": 3} silently replaced --steps, {"seed": 3} did nothing
    from trackjam.experiments.experiment import Configuration, Experiment

    e = Experiment("mine", "", (Configuration(1, "a", settings),), "mine.png")
    with pytest.raises(ValueError, match=f"configuration 1 sets {next(iter(settings))}, which every trial sets itself"):
        base_data(e, steps=3)
