"""The swarm figure: each panel's metric against K, one line per N through the cells' means, a
band that never leaves [floor, 1] for a share, and the one-target engine's cells beside K = 1."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trackjam.experiments.definitions import get_experiment
from trackjam.experiments.swarm_figure import band, swarm_figure


def _rows(experiment, ci: float) -> list[dict]:
    rows = []
    for c in experiment.configurations:
        row = {"config": c.index, "label": c.label, **c.columns}
        K, N = c.cell
        for stem, _, _ in experiment.metrics:
            row[f"{stem}_mean"], row[f"{stem}_ci95"] = 0.1 * K + 0.01 * N + (0.5 if c.one_target else 0.0), ci
        rows.append(row)
    return rows


def test_a_band_is_cut_at_the_floor_and_the_ceiling():
    low, high = band([0.1, 0.9, 0.5, 2.0], [0.3, 0.3, math.nan, 1.0], floor=0.0, ceiling=1.0)
    assert low == pytest.approx([0.0, 0.6, 0.5, 1.0]) and high == pytest.approx([0.4, 1.0, 0.5, 1.0])


def test_one_line_per_team_size_through_the_means():
    e = get_experiment("swarm")
    fig = swarm_figure(e, _rows(e, ci=5.0))
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in axes] == [p.title for p in e.panels]
    for ax, panel in zip(axes, e.panels):
        lines = [ln for ln in ax.get_lines() if ln.get_label().startswith("N = ")]
        assert [ln.get_label() for ln in lines] == ["N = 3", "N = 4", "N = 5", "N = 6"]
        for ln, n in zip(lines, (3, 4, 5, 6)):
            np.testing.assert_array_equal(ln.get_xdata(), [1, 2, 3, 4])
            np.testing.assert_allclose(ln.get_ydata(), [0.1 * k + 0.01 * n for k in (1, 2, 3, 4)])
        for poly in ax.collections:  # the bands (and the reference's error bars)
            for path in poly.get_paths():
                y = path.vertices[:, 1]
                assert y.min() >= panel.floor - 1e-12
                if panel.ylabel.startswith("share"):
                    assert y.max() <= 1.0 + 1e-12
    handles, labels = axes[0].get_legend_handles_labels()
    assert "one-target engine" in labels


def test_the_ceiling_is_a_dashed_line_per_team_size_in_the_panels_that_name_it():
    e = get_experiment("swarm")
    rows = _rows(e, ci=0.05)
    for r in rows:
        r["ceiling_mean"], r["ceiling50_mean"] = 0.9 - 0.1 * r["targets"], 0.8 - 0.01 * r["agents"]
    fig = swarm_figure(e, rows)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    with_reference = {p.title: p.series[1][0] for p in e.panels if len(p.series) > 1}
    assert set(with_reference) == {"(a) held share per target", "(c) targets held on >= 50 % of their steps"}
    for ax, panel in zip(axes, e.panels):
        dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--" and len(ln.get_xdata())]
        if panel.title not in with_reference:
            assert not dashed
            continue
        assert len(dashed) == 4  # one per N, through that N's swarm-engine cells
        assert ax.get_legend() is not None and dict(zip(*ax.get_legend_handles_labels()[::-1])).get(panel.series[1][1])
        want = {"ceiling": lambda k, n: 0.9 - 0.1 * k, "ceiling50": lambda k, n: 0.8 - 0.01 * n}[with_reference[panel.title]]
        for ln, n in zip(dashed, (3, 4, 5, 6)):
            np.testing.assert_allclose(ln.get_ydata(), [want(k, n) for k in (1, 2, 3, 4)])


def test_an_ospa_band_stops_at_the_cut_off():
    e = get_experiment("swarm")
    fig = swarm_figure(e, _rows(e, ci=50.0), ospa_cutoff=10.0)
    for ax, panel in zip(fig.axes, e.panels):
        if panel.series[0][0] == "ospa":
            tops = [path.vertices[:, 1].max() for poly in ax.collections for path in poly.get_paths()]
            assert max(tops) == pytest.approx(10.0)
