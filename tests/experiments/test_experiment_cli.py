"""`trackjam experiment`'s body: runs the sweep, prints the table, and names what it wrote."""

from __future__ import annotations

import functools

from sweep_helpers import fake_trial

import trackjam.experiments.cli as experiment_cli
from trackjam.experiments.engine import run_experiment


def test_the_command_prints_one_row_per_configuration_and_the_files(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(experiment_cli, "run_experiment", functools.partial(run_experiment, trial=fake_trial, progress="none"))
    experiment_cli.experiment_command("constraints", trials=2, steps=3, seed=1, workers=1, out=tmp_path)
    text = capsys.readouterr().out
    assert "constraints on" in text and "constraints off" in text
    assert "ran 4 trials; wrote summary.csv, timing.csv, paired.csv, fig5.png" in text
    experiment_cli.experiment_command("constraints", trials=2, steps=3, seed=1, workers=1, out=tmp_path)
    assert "all trials were already in OUT" in capsys.readouterr().out


def test_the_swarm_tables_show_every_header_and_label_whole(tmp_path, monkeypatch, capsys):
    # at a fixed 220 columns the swarm grid's 17 columns were cut: 'held_airbor…', 'configurati…'
    monkeypatch.setattr(experiment_cli, "run_experiment", functools.partial(run_experiment, progress="none"))
    experiment_cli.experiment_command("swarm", trials=1, steps=2, seed=0, workers=1, out=tmp_path, grid="1x3")
    text = capsys.readouterr().out
    assert "…" not in text
    assert max(len(line) for line in text.splitlines()) < 300  # wrapped between words, not one line per row
    for whole in ("configuration", "held_airborne", "time_to_down", "one-target"):
        assert whole in text, whole
