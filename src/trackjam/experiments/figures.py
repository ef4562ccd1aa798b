"""An experiment's figure: the panels its definition names (default: the paper's Fig. 4), one
bar per configuration and series with its 95 % confidence interval, from summary.csv's rows.

An interval is clipped at its panel's physical floor (no negative incidents, watts or metres):
with few trials the t-interval is wide and would otherwise reach below zero.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure


def _num(v: Any) -> float:
    if v is None or v == "":
        return math.nan
    return float(v)


def error_bars(means: list[float], ci95: list[float], floor: float) -> list[list[float]]:
    """[below, above] error-bar lengths: the interval's half-width, the part below cut at
    ``floor`` (NaN intervals draw no bar)."""
    below, above = [], []
    for m, e in zip(means, ci95):
        e = 0.0 if math.isnan(e) or math.isnan(m) else e
        below.append(max(min(e, m - floor), 0.0) if not math.isnan(m) else 0.0)
        above.append(e)
    return [below, above]


def experiment_figure(experiment, rows: list[dict[str, Any]]) -> Figure:
    """The figure of ``experiment`` (its ``panels``) over summary rows ``rows``."""
    panels = experiment.panels
    ncols = 2 if len(panels) > 1 else 1
    nrows = math.ceil(len(panels) / ncols)
    fig = Figure(figsize=(5 * ncols, 3.5 * nrows))  # no pyplot: no global state, no GUI backend
    axes = list(fig.subplots(nrows, ncols, squeeze=False).flat)
    x = list(range(len(rows)))
    ticks = [str(r["config"]) if experiment.xlabel else str(r["label"]) for r in rows]
    for ax, panel in zip(axes, panels):
        width = 0.8 / len(panel.series)
        values = []
        for i, (stem, legend) in enumerate(panel.series):
            m = [_num(r[f"{stem}_mean"]) for r in rows]
            e = [_num(r[f"{stem}_ci95"]) for r in rows]
            offset = (i - (len(panel.series) - 1) / 2) * width
            ax.bar([v + offset for v in x], m, width, yerr=error_bars(m, e, panel.floor), capsize=3, label=legend)
            values += m
        if len(panel.series) > 1:
            ax.legend()
            if all(v > 0 for v in values if not math.isnan(v)):
                ax.set_yscale("log")
        ax.set_title(panel.title)
        ax.set_ylabel(panel.ylabel)
        ax.set_xticks(x, ticks)
    for ax in axes[len(panels):]:  # an odd number of panels leaves a cell empty
        ax.set_visible(False)
    fig.suptitle(f"{experiment.description} (mean and 95% CI over trials)", fontsize=10)
    if experiment.xlabel:
        fig.supxlabel(experiment.xlabel, fontsize=9)
    fig.tight_layout()
    return fig


def write_figure(experiment, rows: list[dict[str, Any]], path: Path) -> Path:
    experiment_figure(experiment, rows).savefig(path, dpi=120)
    return path
