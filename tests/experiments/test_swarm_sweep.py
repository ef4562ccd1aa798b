"""`trackjam experiment swarm` on real (short) runs: one row per cell with its K and N, each
row's figures the mean of its trials' records, the one-target engine's trials judged as the
swarm engine's, the figure, and a resume that refuses another grid."""

from __future__ import annotations

import io
import math
from contextlib import redirect_stdout

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from trackjam.cli import app
from trackjam.errors import ConfigError
from trackjam.experiments.cli import experiment_command
from trackjam.experiments.engine import run_experiment
from trackjam.experiments.summary import mean_ci95, read_table
from trackjam.experiments.swarm import one_target_estimates
from trackjam.metrics.multi import multi_track_quality, ospa_series
from trackjam.metrics.track_quality import track_quality

SHORT = ["filter.particles=400", "filter.birth_particles=150"]
GRID = "1,2x2,3"


@pytest.fixture(scope="module")
def swarm(tmp_path_factory):
    out = tmp_path_factory.mktemp("swarm")
    printed = io.StringIO()
    with redirect_stdout(printed):
        experiment_command("swarm", trials=2, steps=5, seed=3, workers=1, out=out, overrides=SHORT, grid=GRID)
    return out, printed.getvalue()


def _records(out):
    recs = {}
    for p in sorted((out / "trials").glob("c*.parquet")):
        r = pq.read_table(p).to_pylist()[0]
        recs[(r["config"], r["trial"])] = r
    return recs


def test_one_row_per_cell_with_its_size_and_engine(swarm):
    out, printed = swarm
    rows = read_table(out / "summary.csv")
    assert [(r["targets"], r["agents"], r["engine"]) for r in rows] == [
        ("1", "2", "swarm"), ("1", "3", "swarm"), ("2", "2", "swarm"), ("2", "3", "swarm"),
        ("1", "2", "one-target"), ("1", "3", "one-target")]
    assert all(r["solver"] == "exact" and r["trials"] == "2" for r in rows)
    assert (out / "swarm.png").stat().st_size > 10_000
    assert "K=2, N=3" in printed and "ran 12 trials" in printed and "held50" in printed


def test_each_row_is_the_mean_of_its_trials(swarm):
    out, _ = swarm
    rows, recs = read_table(out / "summary.csv"), _records(out)
    for row in rows:
        mine = [recs[(int(row["config"]), k)] for k in range(2)]
        for stem, key in (("held", "held_share"), ("ospa", "ospa_mean"), ("downed", "downed_share"),
                          ("incidents", "jamming_incidents_per_agent"), ("held_airborne", "held_airborne_share")):
            mean, _ = mean_ci95(r[key] for r in mine)
            assert float(row[f"{stem}_mean"]) == pytest.approx(mean, rel=1e-5), (row["label"], stem)
        # the time to down is over the trials that downed a target
        downed = [r["downed_step_mean"] for r in mine if not math.isnan(r["downed_step_mean"])]
        if downed:
            assert float(row["time_to_down_mean"]) == pytest.approx(np.mean(downed), rel=1e-5)
        else:
            assert row["time_to_down_mean"] == ""
        for r in mine:  # a record's per-target lists give its figures
            assert r["held_share"] == pytest.approx(np.nanmean(r["target.held_share"]))
            assert r["downed_share"] == pytest.approx(np.mean(~np.isnan(r["target.downed_at"])))
            assert len(r["target.held_share"]) == int(row["targets"])
            assert len(r["jamming_incidents"]) == int(row["agents"])


def test_the_paired_table_is_the_mean_difference_of_the_paired_trials(swarm):
    out, _ = swarm
    recs, rows = _records(out), read_table(out / "paired.csv")
    assert [r["label"] for r in rows] == ["K=1: N=2 -> N=3", "K=2: N=2 -> N=3", "N=2: K=1 -> K=2", "N=3: K=1 -> K=2",
                                          "K=1, N=2: one-target engine -> swarm engine",
                                          "K=1, N=3: one-target engine -> swarm engine"]
    for r in rows:
        a, b = int(r["a"]), int(r["b"])
        d = [recs[(b, k)]["ospa_mean"] - recs[(a, k)]["ospa_mean"] for k in range(2)]
        assert float(r["ospa_diff"]) == pytest.approx(np.mean(d), rel=1e-5, abs=1e-9)


def test_the_k1_cells_of_both_engines_start_from_the_same_trial(swarm):
    out, _ = swarm
    recs = _records(out)
    # configurations 1 (K=1, N=2, swarm) and 5 (the same cell, one-target engine)
    for k in range(2):
        assert recs[(1, k)]["seed"] == recs[(5, k)]["seed"] == recs[(3, k)]["seed"]


def test_the_one_target_engine_is_judged_as_the_swarm_engine_judges():
    """A one-target run's steps as a swarm run's: held is its held, OSPA its OSPA."""
    from trackjam.experiments.definitions import base_data, base_scenario, get_experiment, swarm_scenario
    from trackjam.simulation.engine import Simulation

    e = get_experiment("swarm", "1x3")
    base = base_data(e, steps=8, overrides=SHORT)
    reference = next(c for c in e.configurations if c.one_target)
    s = swarm_scenario(e, base_scenario(base), base, reference, 0, 11)
    sim = Simulation(s)
    while not sim.done:
        sim.step()
    steps = sim.result().steps
    truth, reports = one_target_estimates(steps)
    q, single = multi_track_quality(truth, reports, 5.0), track_quality(steps, 5.0)
    assert q["held_steps"] == [single["held_steps"]]
    assert q["missed_steps"] == [single["missed_steps"] + single["false_track_steps"]]
    np.testing.assert_allclose(ospa_series(truth, reports)[:, 0], steps["ospa"])


def test_a_rerun_with_another_grid_is_refused(swarm):
    out, _ = swarm
    with pytest.raises(ConfigError, match="grid: '1,2x2,3' there, '1x2' now"):
        run_experiment("swarm", trials=2, steps=5, seed=3, workers=1, out=out, overrides=SHORT, grid="1x2",
                       progress="none")


def test_the_command_line_refuses_a_bad_grid_in_one_line(tmp_path):
    r = CliRunner().invoke(app, ["experiment", "swarm", "--grid", "0x3", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "--grid" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(app, ["experiment", "table1", "--grid", "1x3", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "has no grid" in r.output
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("grid", ["1x3", "1x2,3"])
def test_an_option_the_swarm_engine_does_not_read_is_refused_up_front_in_a_grid_of_one_target(tmp_path, grid):
    # its K = 1 cells list their one target and run on the swarm engine: only cells of K >= 2
    # were checked, so the sweep started, wrote OUT, and its first trial failed on the option
    r = CliRunner().invoke(app, ["experiment", "swarm", "--grid", grid, "--trials", "1", "--steps", "2", "--workers",
                                 "1", "--set", "control.plan_over=belief", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert r.output.startswith("trackjam: error: --set control.plan_over=belief: control.plan_over: 'belief' is not "
                               "simulated with several targets yet") and r.output.count("\n") == 1
    assert not (tmp_path / "o").exists()


def test_the_solver_column_names_the_solver_every_trial_of_the_row_runs():
    """summary.csv's `solver` is read from the cell's first trial; every trial of every cell, on
    either engine, runs that solver (both engines plan with the scenario's control.solver), and
    a --set of it is what the column says."""
    from trackjam.experiments.engine import _plan
    from trackjam.experiments.swarm import swarm_experiment

    for overrides, solver in ((SHORT, "exact"), ([*SHORT, "control.solver=greedy"], "greedy")):
        experiment = swarm_experiment("1x2,3")
        scenarios, rows = _plan(experiment, 2, 3, 0, overrides)
        assert [(r["label"], r["solver"]) for r in rows] == [(c.label, solver) for c in experiment.configurations]
        assert {s.control.solver for s in scenarios.values()} == {solver}
        assert {s.targets is None for s in scenarios.values()} == {True, False}  # both engines
