"""The swarm experiment's grid, trial draw and scenarios, and the record a trial reduces to:
cells of one trial share their targets and agents (paired comparisons across N), every cell is
the swarm-3 settings with the jamming response on, and the figures of a record are the ones its
per-step classes give."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.experiments.definitions import (
    SWARM,
    base_data,
    base_scenario,
    get_experiment,
    swarm_experiment,
    swarm_scenario,
)
from trackjam.experiments.swarm import DEFAULT_GRID, NODE_LIMIT, airborne_shares, draw_swarm, parse_grid, swarm_record
from trackjam.experiments.trials import BALL_RADIUS_M
from trackjam.metrics.multi import HELD, MISSED, UNDETECTABLE, multi_track_quality


def _scenarios(grid=None, k=0, seed=0, overrides=()):
    e = get_experiment("swarm", grid)
    base = base_data(e, steps=30, overrides=list(overrides))
    space = base_scenario(base, e.preset)
    return {c.label: swarm_scenario(e, space, base, c, k, seed) for c in e.configurations}


@pytest.mark.parametrize("text, grid", [
    (None, DEFAULT_GRID),
    ("1-4x3-6", ((1, 2, 3, 4), (3, 4, 5, 6))),
    ("3x5", ((3,), (5,))),
    ("2,4x3, 6", ((2, 4), (3, 6))),
    ("1-2,4x5,3", ((1, 2, 4), (3, 5))),
])
def test_a_grid_is_targets_by_agents_lists_or_ranges(text, grid):
    assert parse_grid(text) == grid


@pytest.mark.parametrize("text, words", [
    ("3", "expected TARGETSxAGENTS"),
    ("x5", "expected TARGETSxAGENTS"),
    ("0x3", "targets '0' must lie within 1..8"),
    ("9x3", "targets '9' must lie within 1..8"),
    ("3-1x4", "targets '3-1' must lie within"),
    ("1,1x3", "lists a value twice"),
    ("ax3", "not a list of whole numbers"),
    ("2x3.5", "agents '3.5' is not a list"),
    ("2x13", "agents '13' must lie within 1..12"),
])
def test_a_bad_grid_is_one_line_naming_the_option(text, words):
    with pytest.raises(ConfigError, match=words.replace(".", r"\.")) as err:
        get_experiment("swarm", text)
    assert str(err.value).startswith("--grid") and "\n" not in str(err.value)


def test_only_the_swarm_experiment_takes_a_grid():
    with pytest.raises(ConfigError, match="--grid: experiment table1 has no grid"):
        get_experiment("table1", "1x3")
    with pytest.raises(ConfigError, match="table1, constraints, solvers, holding, comms, oracles, swarm"):
        get_experiment("swarm3")


def test_the_default_grid_is_sixteen_cells_and_the_one_target_check():
    e = get_experiment("swarm")
    assert e.trials == SWARM and e.grid == "1,2,3,4x3,4,5,6" and e.preset == "swarm-3"
    cells = [(c.cell, c.one_target) for c in e.configurations]
    assert cells == [((k, n), False) for k in (1, 2, 3, 4) for n in (3, 4, 5, 6)] + [((1, n), True) for n in (3, 4, 5, 6)]
    assert [c.index for c in e.configurations] == list(range(1, 21))
    # without K = 1 there is nothing for the one-target engine to check
    assert [c.label for c in swarm_experiment("2x3,4").configurations] == ["K=2, N=3", "K=2, N=4"]


def test_the_draw_nests_targets_across_k_and_agents_across_n():
    low, high = np.zeros(3), np.full(3, 100.0)
    small, large = draw_swarm(5, 2, 2, 3, low, high, 3.0), draw_swarm(5, 2, 3, 3, low, high, 3.0)
    np.testing.assert_array_equal(small.x0, large.x0[:2])  # one more target, the others the same
    fewer, more = draw_swarm(5, 2, 3, 3, low, high, 3.0), draw_swarm(5, 2, 3, 5, low, high, 3.0)
    np.testing.assert_array_equal(fewer.u0, more.u0[:3])  # one more agent, the others the same
    assert not np.array_equal(draw_swarm(5, 3, 3, 5, low, high, 3.0).x0, more.x0)  # another trial
    for d in (small, large, more):
        K = len(d.x0)
        assert np.all((d.x0[:, :3] >= low) & (d.x0[:, :3] <= high)) and np.all(np.abs(d.x0[:, 3:]) <= 3.0)
        assert np.all((d.u0 >= low) & (d.u0 <= high))
        for j, u in enumerate(d.u0):  # agent j in the ball around target j mod K
            assert np.linalg.norm(u - d.x0[j % K, :3]) <= BALL_RADIUS_M


def test_the_ball_around_a_target_in_a_corner_is_cut_to_the_area():
    # many draws: every agent inside, as the rejection promises, even for targets near the walls
    low, high = np.zeros(3), np.full(3, 100.0)
    for k in range(40):
        d = draw_swarm(1, k, 4, 6, low, high, 3.0)
        assert np.all((d.u0 >= low) & (d.u0 <= high))


def test_every_cell_is_swarm3_with_its_targets_landing_when_jammed():
    # the experiment keeps the cue at rest, as its published results were measured, and its
    # filters expect the targets' fail-safe
    # and its exact searches stop at a node budget, never at the clock, so a sweep repeats under any load
    preset = load_scenario("swarm-3", overrides=["filter.cue.velocity=zero", "filter.response={action: land}",
                                                 f"control.node_limit={NODE_LIMIT}", "control.time_limit_s=3600"])
    assert NODE_LIMIT > 0
    ss = _scenarios(k=1, seed=4)
    for label, s in ss.items():
        for section in ("antenna", "sensor", "filter", "fusion", "control"):
            mine, theirs = getattr(s, section).model_dump(), getattr(preset, section).model_dump()
            if section == "control":
                mine["grasp"].pop("threads"), theirs["grasp"].pop("threads")
            assert mine == theirs, (label, section)
        assert all(t.response is not None and t.response.action == "land" for t in s.target_list)
        assert all(t.response.threshold_db == -40 and t.response.steps == 3 for t in s.target_list)
        expected = s.filter.response.model_dump()
        assert expected.pop("hedge") == 0.0 and expected == s.target_list[0].response.model_dump()
        assert s.agents.initial_aim is None and s.steps == 30
    s = ss["K=3, N=5"]
    assert s.targets is not None and len(s.targets) == 3 and s.n_agents == 5
    assert s.antenna.pointing == "aim" and s.control.solver == "exact" and s.fusion.share == "scans"
    assert s.filter.cue is not None


def test_the_cells_of_a_trial_share_targets_agents_and_seed():
    ss, other = _scenarios(k=1, seed=4), _scenarios(k=2, seed=4)
    assert len({s.seed for s in ss.values()}) == 1 and other["K=1, N=3"].seed != ss["K=1, N=3"].seed
    a, b = ss["K=3, N=4"], ss["K=3, N=6"]
    assert a.targets == b.targets and b.agents.initial[:4] == a.agents.initial
    assert ss["K=2, N=4"].targets == a.targets[:2]
    # the one-target engine's cell is the K = 1 swarm cell with `target:` instead of a list of one
    one, swarm = ss["K=1, N=5, one-target engine"], ss["K=1, N=5"]
    assert one.targets is None and len(swarm.targets) == 1
    assert one.target.model_dump() == swarm.target.model_dump() and one.agents == swarm.agents


@pytest.mark.parametrize("override, words", [
    ("targets=[]", "set by every trial"),
    ("target.response=null", "set by every trial"),
    ("agents.initial=[[1, 2, 3]]", "set by every trial"),
    ("steps=5", "--steps"),
])
def test_keys_the_trials_set_are_refused(override, words):
    with pytest.raises(ConfigError, match=words) as err:
        _scenarios("1x3", overrides=[override])
    assert "\n" not in str(err.value)


def test_other_overrides_reach_every_cell():
    ss = _scenarios("1,2x3", overrides=["filter.particles=700", "control.team_objective=min"])
    assert all(s.filter.particles == 700 and s.control.team_objective == "min" for s in ss.values())


def test_a_cell_the_scenario_cannot_take_is_one_line():
    with pytest.raises(ConfigError, match="at_least") as err:
        _scenarios("1x1", overrides=["control.at_least=2"])
    assert "\n" not in str(err.value)


# ---------------------------------------------------------------------------------------------
# the record of a trial


def _truth_and_reports(classes: np.ndarray):
    """A truth (T, K, 3) and reports that make exactly ``classes`` (HELD: a track on the target)."""
    T, K = classes.shape
    truth = np.full((T, K, 3), np.nan)
    reports = []
    for t in range(T):
        pos = []
        for k in range(K):
            if classes[t, k] != UNDETECTABLE:
                truth[t, k] = [20.0 * k + 10, 50, 50]
            if classes[t, k] == HELD:
                pos.append(truth[t, k] + [1.0, 0, 0])
        reports.append((np.array([f"l{i}" for i in range(len(pos))]), np.array(pos).reshape(-1, 3)))
    return truth, reports


def test_the_record_is_what_the_per_step_classes_give():
    H, M, U = HELD, MISSED, UNDETECTABLE
    classes = np.array([[H, H, U], [H, M, U], [M, M, H], [H, M, H]], dtype=np.int8)
    quality = multi_track_quality(*_truth_and_reports(classes), gate=5.0, ids=[0, 1, 2])
    ospa = np.array([[1.0, 1.0, 0.0], [5.0, 3.0, 4.0], [7.0, 1.0, 6.0], [3.0, 1.0, 2.0]])
    r = swarm_record(quality, classes, ospa, downed_at=[2, None, 4], incidents=[0, 2, 1], transmit_w=0.5,
                     step_s=0.1, solve_s=0.01, steps={"t": np.arange(1, 5)}, ceiling=[1.0, 0.25, None])
    # per target held 3/4, 1/4, 2/2: mean, >= 50 %, missed over all detectable target-steps
    assert r["held_share"] == pytest.approx((0.75 + 0.25 + 1.0) / 3)
    assert r["held50_share"] == pytest.approx(2 / 3)
    assert r["missed_share"] == pytest.approx(4 / 10)
    # airborne: target 0 over steps 1-2 (2/2), target 1 never downed (1/4), target 2 over 1-4 (2/2)
    assert airborne_shares(classes, [2, None, 4]) == pytest.approx([1.0, 0.25, 1.0])
    assert r["held_airborne_share"] == pytest.approx(0.75)
    assert r["downed_share"] == pytest.approx(2 / 3) and r["downed_step_mean"] == 3.0
    assert r["ospa_mean"] == 4.0 and r["ospa_card_mean"] == 3.0
    assert r["jamming_incidents_per_agent"] == 1.0 and r["false_tracks_per_step"] == 0.0
    assert r["targets"]["held_share"] == pytest.approx([0.75, 0.25, 1.0])
    assert r["targets"]["downed_at"][0] == 2 and math.isnan(r["targets"]["downed_at"][1])
    np.testing.assert_array_equal(r["steps"]["held_targets"], [2, 1, 1, 2])
    # the ceiling: over the targets that have one (never detectable: None)
    assert r["ceiling_share"] == pytest.approx(0.625) and r["ceiling50_share"] == 0.5
    assert r["targets"]["ceiling_share"][:2] == [1.0, 0.25] and math.isnan(r["targets"]["ceiling_share"][2])


def test_a_record_without_a_downed_target_has_no_time_to_down():
    classes = np.array([[HELD], [MISSED]], dtype=np.int8)
    quality = multi_track_quality(*_truth_and_reports(classes), gate=5.0)
    r = swarm_record(quality, classes, np.zeros((2, 3)), downed_at=[None], incidents=[0], transmit_w=0.0,
                     step_s=0.1, solve_s=0.01, steps={}, ceiling=[1.0])
    assert r["downed_share"] == 0.0 and math.isnan(r["downed_step_mean"])
    assert r["held_airborne_share"] == r["held_share"] == 0.5 and r["held50_share"] == 1.0


def test_a_false_track_counts_per_step():
    classes = np.array([[HELD], [MISSED]], dtype=np.int8)
    truth, reports = _truth_and_reports(classes)
    reports[1] = (np.array(["x"]), np.array([[90.0, 90.0, 90.0]]))  # confirmed, far from the target
    quality = multi_track_quality(truth, reports, gate=5.0)
    r = swarm_record(quality, classes, np.zeros((2, 3)), downed_at=[None], incidents=[0], transmit_w=0.0,
                     step_s=0.1, solve_s=0.01, steps={}, ceiling=[1.0])
    assert r["false_tracks_per_step"] == 0.5 and r["missed_share"] == 0.5


def test_the_time_to_down_is_averaged_over_the_trials_that_downed_a_target():
    from trackjam.experiments.summary import table_rows

    conf = [{"config": 1, "label": "K=2, N=3", "n_controls": 79, "opening_angle_deg": 80.0, "constraints": True,
             "solver": "exact", "targets": 2, "agents": 3, "engine": "swarm"}]
    records = [{"config": 1, "trial": k, "downed_step_mean": v, "downed_share": d}
               for k, (v, d) in enumerate([(3.0, 0.5), (math.nan, 0.0), (5.0, 1.0)])]
    metrics = (("time_to_down", "downed_step_mean", ""), ("downed", "downed_share", ""))
    row = table_rows(records, conf, metrics)[0]
    assert row["time_to_down_mean"] == 4.0 and row["time_to_down_ci95"] > 0  # over 3 and 5
    assert row["downed_mean"] == pytest.approx(0.5)  # the share counts every trial
    assert list(row)[:10] == [*conf[0], "trials"]  # the cell's columns follow the common ones


def test_the_pairs_compare_neighbours_extremes_and_the_two_engines():
    e = get_experiment("swarm")
    index = {(c.cell, c.one_target): c.index for c in e.configurations}
    pairs = {label: (a, b) for a, b, label in e.pairs}
    assert len(pairs) == 4 * 4 + 4 * 4 + 4
    assert pairs["K=3: N=4 -> N=5"] == (index[((3, 4), False)], index[((3, 5), False)])
    assert pairs["K=2: N=3 -> N=6"] == (index[((2, 3), False)], index[((2, 6), False)])
    assert pairs["N=5: K=1 -> K=4"] == (index[((1, 5), False)], index[((4, 5), False)])
    assert pairs["K=1, N=6: one-target engine -> swarm engine"] == (index[((1, 6), True)], index[((1, 6), False)])
    # two values have no extremes beyond their one neighbour pair, one value no pair at all
    assert [label for _, _, label in swarm_experiment("2x3,4").pairs] == ["K=2: N=3 -> N=4"]


def test_a_paired_difference_is_over_the_trials_both_ran():
    from trackjam.experiments.summary import mean_ci95, paired_rows

    a = [1.0, 2.0, 4.0, math.nan]
    b = [2.0, 2.5, 7.0, 1.0, 9.0]  # its trial 4 has no partner; trial 3 lacks a's value
    records = [{"config": 1, "trial": k, "x": v} for k, v in enumerate(a)]
    records += [{"config": 2, "trial": k, "x": v} for k, v in enumerate(b)]
    row = paired_rows(records, [(1, 2, "one -> two")], (("x", "x", ""),))[0]
    assert row["trials"] == 4 and row["label"] == "one -> two"
    assert (row["x_diff"], row["x_ci95"]) == pytest.approx(mean_ci95([1.0, 0.5, 3.0]))


def test_differences_equal_but_for_rounding_have_an_interval_of_zero():
    from scipy import stats

    from trackjam.experiments.summary import mean_ci95

    d = [1 / 3 - 2 / 3, 2 / 3 - 1.0]  # -1/3 twice, but for the last bit
    assert d[0] != d[1] and np.std(d, ddof=1) > 0
    assert mean_ci95(d) == (pytest.approx(-1 / 3), 0.0)
    x = [0.5, 1.5, 4.0]  # a real spread keeps its t-interval
    assert mean_ci95(x)[1] == pytest.approx(stats.t.ppf(0.975, 2) * np.std(x, ddof=1) / np.sqrt(3))
    # ... however small, once it is past rounding: a relative spread of 1e-9 (a million times the
    # last bit) keeps its interval (a tolerance of 1e-2 set the interval of [1, 1.001] to 0)
    for y in ([1.0, 1.0 + 1e-9], [1.0, 1.001, 0.9995], [1e6, 1e6 + 1e-3]):
        want = stats.t.ppf(0.975, len(y) - 1) * statistics.stdev(y) / math.sqrt(len(y))
        assert want > 0 and mean_ci95(y)[1] == pytest.approx(want, rel=1e-5), y
