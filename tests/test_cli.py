"""The command line: presets, show-config, validate, and bad input (one line, exit 2)."""

import subprocess
import sys

import pytest
import yaml
from typer.testing import CliRunner

from trackjam.cli import app

runner = CliRunner()


def test_presets_lists_paper_fig3():
    r = runner.invoke(app, ["presets"])
    assert r.exit_code == 0 and "paper-fig3" in r.output


def test_show_config_prints_the_resolved_scenario_with_overrides():
    r = runner.invoke(app, ["show-config", "paper-fig3", "--set", "antenna.opening_angle_deg=120"])
    assert r.exit_code == 0
    data = yaml.safe_load(r.output)
    assert data["antenna"]["opening_angle_deg"] == 120 and data["control"]["samples"] == 10000


def test_validate_accepts_a_good_file(tmp_path):
    f = tmp_path / "ok.yaml"
    f.write_text("name: ok\nsteps: 4\n")
    r = runner.invoke(app, ["validate", str(f)])
    assert r.exit_code == 0 and "ok" in r.output


@pytest.mark.parametrize(
    "text, key",
    [
        ("antena: {height: 3}\n", "antena"),
        ("steps: many\n", "steps"),
        ("antenna: {height: -40}\n", "antenna.height"),
        ("antenna: {opening_angle_deg: 190}\n", "antenna.opening_angle_deg"),
        ("antenna: {power_levels_db: []}\n", "antenna.power_levels_db"),
        ("antenna: {r0: .nan}\n", "antenna.r0"),
        ("steps: [\n", "YAML"),
    ],
)
def test_bad_files_exit_2_with_one_line(tmp_path, text, key):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", str(f)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and key in lines[0]


def test_missing_file_exits_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", str(tmp_path / "nope.yaml")], capture_output=True, text=True)
    assert r.returncode == 2 and "no such file" in r.stderr and "Traceback" not in r.stderr


def test_bad_set_exits_2():
    r = runner.invoke(app, ["show-config", "paper-fig3", "--set", "antenna.height"])
    assert r.exit_code == 2
