"""``control.close_in`` in a whole run: with 7 m steps the paper's one-step objective spreads the
team away from the target at the first step (every plan that closes in breaks Eq. 13, and a
plan that spreads out is worth a sliver of Xi); closing in keeps it on the target, unjammed."""

import json
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
from readme_tables import closing_table_rows

from trackjam.config.loading import load_scenario
from trackjam.simulation.loop import simulate


def _run(close_in):
    r = simulate(load_scenario("pursuit", seed=1, steps=3, agents__radial_steps=[1, 3, 5, 7],
                               control__close_in=close_in, filter__particles=2000, filter__birth_particles=500))
    s, a = r.steps, r.agents
    truth = np.c_[s["truth_x"], s["truth_y"], s["truth_z"]]
    pos = np.c_[a["x"], a["y"], a["z"]].reshape(len(truth), -1, 3)
    return s, a, np.linalg.norm(pos - truth[:, None, :], axis=2).mean(axis=1)


def test_faster_agents_close_in_instead_of_spreading_out():
    s0, a0, d0 = _run(None)
    s1, a1, d1 = _run(0.05)
    assert not np.any(s0["closed_in"])  # off: the paper's plan at every step
    assert s0["objective"][0] < 0.05 and s1["closed_in"][0]  # the first step's best plan is worth next to nothing
    assert not np.any(a1["jammed"])  # Eq. (13) still holds: the levels keep it
    assert d1[-1] < d0[-1] - 5.0  # after three steps the team is nearer the target by more than 5 m
    assert s1["objective"][-1] > 0.5 > s0["objective"][-1]



def test_the_run_counts_its_closed_in_steps_in_the_summary_and_the_closing_table(tmp_path):
    out = tmp_path / "run"
    args = ["run", "pursuit", "--seed", "1", "--set", "steps=3", "--set", "agents.radial_steps=[1, 3, 5, 7]",
            "--set", "filter.particles=2000", "--set", "filter.birth_particles=500", "--set", "control.close_in=0.05",
            "--no-figures", "--out", str(out)]
    shown = subprocess.run([sys.executable, "-m", "trackjam", *args], capture_output=True, text=True, check=True).stdout
    summary = json.loads((out / "summary.json").read_text())
    closed = sum(pq.read_table(out / "steps.parquet").column("closed_in").to_pylist())
    assert summary["closed_in_steps"] == closed >= 1
    assert closing_table_rows(shown)["steps closed in (control.close_in 0.05)"] == str(closed)
