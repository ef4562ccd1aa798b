"""`trackjam run`: the output folder, its files, and refusing to overwrite what is not ours."""

import json
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.simulation.output import check_out_dir

FAST = ["steps=4", "control.solver=exact", "filter.particles=500", "filter.birth_particles=200"]


def trackjam(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "trackjam", *args], capture_output=True, text=True, cwd=cwd)


def sets(items):
    return [a for it in items for a in ("--set", it)]


def test_run_writes_every_file(tmp_path):
    out = tmp_path / "run"
    r = trackjam("run", "paper-fig3", "--out", str(out), *sets(FAST))
    assert r.returncode == 0, r.stderr
    for name in ["scenario.yaml", "summary.json", "steps.parquet", "agents.parquet", "measurements.parquet", "run.png", "replay.html"]:
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 1 and "version" in summary and len(summary["jamming_incidents"]) == 3
    steps = pq.read_table(out / "steps.parquet").to_pydict()
    assert steps["t"] == [1, 2, 3, 4]
    assert np.mean(steps["ospa"]) == pytest.approx(summary["ospa_mean"])
    assert "mean OSPA" in r.stdout  # the closing table
    # its track quality is the summary's, judged by the truth, never "existence > 0.5"
    n = summary["detectable_steps"]
    assert "held (confirmed, within 5 m) / detectable steps" in r.stdout
    assert f"{summary['held_steps']}/{n}" in r.stdout and f"{summary['missed_steps']}/{n}" in r.stdout
    assert "ceiling: a chaser within 8 m" in r.stdout and "existence > 0.5" not in r.stdout
    assert steps["quality"].count("held") == summary["held_steps"]
    assert "step 4/4" in r.stdout  # one plain line per step when not on a terminal
    # the same scenario again into the same folder is allowed and reproduces the logs
    r2 = trackjam("run", "paper-fig3", "--out", str(out), *sets(FAST))
    assert r2.returncode == 0, r2.stderr
    assert pq.read_table(out / "steps.parquet").to_pydict()["existence"] == steps["existence"]


def test_out_pointing_at_a_file_is_refused_and_the_file_kept(tmp_path):
    f = tmp_path / "precious.txt"
    f.write_text("keep me")
    r = trackjam("run", "paper-fig3", "--out", str(f), *sets(FAST))
    assert r.returncode == 2 and "is a file" in r.stderr and "Traceback" not in r.stderr
    assert f.read_text() == "keep me"


def test_out_holding_another_scenario_is_refused_and_untouched(tmp_path):
    out = tmp_path / "run"
    assert trackjam("run", "paper-fig3", "--out", str(out), "--no-figures", *sets(FAST)).returncode == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    r = trackjam("run", "paper-fig3", "--out", str(out), "--seed", "5", *sets(FAST))
    assert r.returncode == 2 and "not empty" in r.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_out_with_foreign_files_is_refused(tmp_path):
    (tmp_path / "notes.md").write_text("mine")
    with pytest.raises(ConfigError, match="not empty"):
        check_out_dir(tmp_path, load_scenario("paper-fig3"))


def test_unwritable_out_is_refused():
    # /sys refuses new files even to root, which plain permission bits would not
    r = trackjam("run", "paper-fig3", "--out", "/sys/trackjam-out", *sets(FAST))
    assert r.returncode == 2 and "not writable" in r.stderr and "Traceback" not in r.stderr


def test_unwritable_out_under_a_file_is_refused(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(ConfigError):
        check_out_dir(f / "sub" / "dir", load_scenario("paper-fig3"))
