"""An experiment's figure: the panels its definition names, intervals clipped at the physical
floor, and a new experiment that brings its own metrics and panels."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sweep_helpers import SWEEP, holding_trial

from trackjam.experiments import definitions
from trackjam.experiments.definitions import FIG4_PANELS, FIG5_PANELS, Configuration, Experiment, Panel, get_experiment
from trackjam.experiments.engine import run_experiment
from trackjam.experiments.figures import error_bars, experiment_figure
from trackjam.experiments.summary import METRICS, read_table


def test_error_bars_stop_at_the_floor():
    below, above = error_bars([1.0, 30.0, 2.0, math.nan], [25.0, 5.0, math.nan, 3.0], floor=0.0)
    assert below == [1.0, 5.0, 0.0, 0.0] and above == [25.0, 5.0, 0.0, 0.0]
    assert error_bars([3.0], [5.0], floor=2.0) == [[1.0], [5.0]]


def test_error_bars_stop_at_the_ceiling_too():
    # a share's t-interval over 2 trials had reached 2.5 in holding.png's panel (a)
    below, above = error_bars([0.4, 0.9, 1.0, math.nan], [2.1, 0.05, 0.3, 1.0], floor=0.0, ceiling=1.0)
    assert below == pytest.approx([0.4, 0.05, 0.3, 0.0]) and above == pytest.approx([0.6, 0.05, 0.0, 0.0])


def test_the_holding_figure_keeps_every_share_within_0_and_1_and_says_when_a_panel_is_empty():
    holding = get_experiment("holding")
    rows = _rows(holding, means=0.5, ci=2.0)  # 2 trials: a t-interval far past 1
    for row in rows:
        row.update({"reacquired": 0, "reacquired_of": 0, "reacquired_lo": "", "reacquired_hi": ""})
    fig = experiment_figure(holding, rows)
    shares, again = fig.axes[0], fig.axes[1]
    for container in shares.containers:
        if hasattr(container, "lines"):
            segments = np.concatenate([lc.get_segments() for lc in container.lines[2]])
            assert segments[:, :, 1].min() == pytest.approx(0.0) and segments[:, :, 1].max() == pytest.approx(1.0)
    assert [t.get_text() for t in again.texts] == [holding.panels[1].empty]
    assert "hidden spell" in holding.panels[1].empty and again.get_ylim() == (0.0, 1.0)
    assert not fig.axes[2].texts  # the OSPA panel has its bars


def _rows(experiment, means: float, ci: float) -> list[dict]:
    rows = []
    for c in experiment.configurations:
        row = {"config": c.index, "label": c.label}
        for stem, _, _ in experiment.metrics:
            row[f"{stem}_mean"], row[f"{stem}_ci95"] = means, ci
        rows.append(row)
    return rows


@pytest.mark.parametrize("name", ["table1", "constraints", "solvers"])
def test_no_interval_is_drawn_below_zero_even_with_two_trials(name):
    experiment = get_experiment(name)
    fig = experiment_figure(experiment, _rows(experiment, means=1.0, ci=25.0))  # 2 trials: t = 12.7
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in axes] == [p.title for p in experiment.panels]
    for ax in axes:
        for container in ax.containers:
            if hasattr(container, "lines"):  # the error bars of a bar series
                segments = np.concatenate([lc.get_segments() for lc in container.lines[2]])
                assert segments[:, :, 1].min() >= 0.0 and segments[:, :, 1].max() == pytest.approx(26.0)


def test_the_paper_experiments_keep_the_papers_panels():
    assert get_experiment("table1").panels == FIG4_PANELS and get_experiment("solvers").panels == FIG4_PANELS
    assert get_experiment("constraints").panels == FIG5_PANELS


HOLDING = Experiment(
    "holding-demo",
    "held, false-track and missed shares, GRASP against exact",
    (Configuration(1, "grasp", {"control.solver": "grasp"}), Configuration(2, "exact", {"control.solver": "exact"})),
    "holding.png",
    panels=(
        Panel("(a) held", "share of steps", (("held", None),)),
        Panel("(b) false track", "share of steps", (("false_track", None),)),
        Panel("(c) missed", "share of steps", (("missed", None),)),
    ),
    metrics=(
        ("held", "held_share", "share of steps with the track held"),
        ("false_track", "false_share", "share of steps on a false track"),
        ("missed", "missed_share", "share of steps the target was missed"),
    ),
)


def test_a_new_experiment_draws_its_own_panels_from_its_own_metrics(tmp_path, monkeypatch):
    monkeypatch.setitem(definitions.EXPERIMENTS, HOLDING.name, HOLDING)
    r = run_experiment(HOLDING.name, workers=1, out=tmp_path, **{**SWEEP, "trial": holding_trial})
    rows = read_table(tmp_path / "summary.csv")
    assert [k for k in rows[0] if k.endswith("_mean")] == ["held_mean", "false_track_mean", "missed_mean"]
    for row in rows:  # shares of the same steps
        assert sum(float(row[f"{s}_mean"]) for s in ("held", "false_track", "missed")) == pytest.approx(1.0, abs=1e-5)
    assert (tmp_path / "holding.png").stat().st_size > 0 and r.files[-1].name == "holding.png"
    fig = experiment_figure(HOLDING, r.summary)
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in visible] == ["(a) held", "(b) false track", "(c) missed"]
    heights = [p.get_height() for p in visible[0].patches]
    assert heights == pytest.approx([row["held_mean"] for row in r.summary])


def test_a_panel_must_show_metrics_the_experiment_has():
    with pytest.raises(ValueError, match=r"panels show \['ospa'\]"):
        Experiment("x", "x", (Configuration(1, "a"),), "x.png", panels=(Panel("t", "y", (("ospa", None),)),),
                   metrics=METRICS[:1])


def test_a_trial_function_missing_a_metric_stops_the_sweep_with_its_name(tmp_path):
    with pytest.raises(ValueError, match="returned no jamming_incidents_per_agent"):
        run_experiment("constraints", workers=1, out=tmp_path, **{**SWEEP, "trial": holding_trial})


def test_a_new_experiment_shows_its_own_metrics_in_the_plain_progress(tmp_path, monkeypatch, capsys):
    """Its trial function returns only its own metrics: the plain lines had printed the paper's
    incidents and OSPA from every record, a KeyError traceback once the first trial ended."""
    monkeypatch.setitem(definitions.EXPERIMENTS, HOLDING.name, HOLDING)
    run_experiment(HOLDING.name, workers=1, out=tmp_path, **{**SWEEP, "trial": holding_trial, "progress": "lines"})
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4 and lines[0].startswith("[1/4] config 1 (grasp) trial 0: held ")
    assert ", false_track " in lines[0] and "running means over all configurations: held " in lines[-1]
    assert [key for _, key, _ in HOLDING.shown] == ["held_share", "false_share", "missed_share"]


def test_shown_figures_must_be_among_the_experiments_metrics():
    with pytest.raises(ValueError, match=r"shown names \['ospa_mean'\], which are not among its metrics' keys"):
        Experiment("x", "x", (Configuration(1, "a"),), "x.png", panels=(), metrics=METRICS[:1],
                   shown=(("OSPA", "ospa_mean", "{:.2f} m"),))


@pytest.mark.parametrize("name", ["holding", "comms", "oracles"])
def test_no_axis_label_runs_into_the_title_or_the_tick_labels(name):
    # panel (b)'s one-line "share of trials (Clopper-Pearson 95%)" was taller than its axes:
    # in oracles.png it ran into the figure's title and the first slanted configuration name
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    experiment = get_experiment(name)
    rows = _rows(experiment, means=0.5, ci=0.1)
    for row in rows:
        row.update({"reacquired": 1, "reacquired_of": 2, "reacquired_lo": 0.1, "reacquired_hi": 0.9})
    fig = experiment_figure(experiment, rows)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    title = fig._suptitle.get_window_extent(renderer)
    ticks = [t.get_window_extent(renderer) for ax in fig.axes for t in ax.get_xticklabels() if t.get_text()]
    for ax in fig.axes:
        label = ax.yaxis.label.get_window_extent(renderer)
        assert not label.overlaps(title), (ax.get_title(), ax.get_ylabel())
        assert not any(label.overlaps(t) for t in ticks), (ax.get_title(), ax.get_ylabel())


def test_an_ospa_interval_stops_at_the_cut_off_no_ospa_exceeds():
    # two trials: fig4.png's OSPA bar of 3.2 m had an interval up to 27 m, with c = 10 m
    experiment = get_experiment("table1")
    fig = experiment_figure(experiment, _rows(experiment, means=1.0, ci=25.0), ospa_cutoff=10.0)
    for ax in fig.axes:
        tops = [np.concatenate([lc.get_segments() for lc in c.lines[2]])[:, :, 1].max()
                for c in ax.containers if hasattr(c, "lines")]
        assert max(tops) == pytest.approx(10.0 if ax.get_ylabel() == "OSPA [m]" else 26.0)


def test_a_sweep_draws_its_ospa_intervals_up_to_its_scenarios_cut_off(tmp_path, monkeypatch):
    from trackjam.experiments import figures

    drawn = {}
    original = figures.write_figure

    def spy(experiment, rows, path, ospa_cutoff=math.inf):
        drawn["c"] = ospa_cutoff
        return original(experiment, rows, path, ospa_cutoff)

    monkeypatch.setattr(figures, "write_figure", spy)
    run_experiment("constraints", workers=1, out=tmp_path, overrides=["metrics.ospa_cutoff=2.5"], **SWEEP)
    assert drawn["c"] == 2.5
