"""An experiment's figure: the panels its definition names (default: the paper's Fig. 4), one
bar per configuration and series with its 95 % confidence interval, from summary.csv's rows.

An interval is clipped at its panel's physical bounds (no negative incidents, watts or metres,
no share above 1, no OSPA above its cut-off c): with few trials the t-interval is wide and would
otherwise reach past them.
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


def error_bars(means: list[float], ci95: list[float], floor: float,
               ceiling: float = math.inf) -> list[list[float]]:
    """[below, above] error-bar lengths: the interval's half-width, the part below cut at
    ``floor`` and the part above at ``ceiling`` (NaN intervals draw no bar)."""
    below, above = [], []
    for m, e in zip(means, ci95):
        e = 0.0 if math.isnan(e) or math.isnan(m) else e
        below.append(max(min(e, m - floor), 0.0) if not math.isnan(m) else 0.0)
        above.append(max(min(e, ceiling - m), 0.0) if not math.isnan(m) else 0.0)
    return [below, above]


# the track-quality classes in the colours of run.png's band (i); the ceiling in grey
COLOURS = {"held": "#2ca02c", "false_track": "#ff7f0e", "missed": "#d62728", "ceiling": "0.6"}


def _series(rows: list[dict[str, Any]], stem: str, floor: float,
            ceiling: float = math.inf) -> tuple[list[float], list[list[float]]]:
    """Bar heights and their [below, above] error lengths: a metric's mean and its ci95, or a
    count's share k / n and its Clopper-Pearson bounds."""
    if f"{stem}_mean" in rows[0]:
        m = [_num(r[f"{stem}_mean"]) for r in rows]
        return m, error_bars(m, [_num(r[f"{stem}_ci95"]) for r in rows], floor, ceiling)
    m, below, above = [], [], []
    for r in rows:
        n = _num(r[f"{stem}_of"])
        share = _num(r[stem]) / n if n > 0 else math.nan
        m.append(share)
        below.append(0.0 if math.isnan(share) else share - _num(r[f"{stem}_lo"]))
        above.append(0.0 if math.isnan(share) else _num(r[f"{stem}_hi"]) - share)
    return m, [below, above]


def experiment_figure(experiment, rows: list[dict[str, Any]], ospa_cutoff: float = math.inf) -> Figure:
    """The figure of ``experiment`` (its ``panels``) over summary rows ``rows``; an OSPA
    interval stops at ``ospa_cutoff``, the c no OSPA exceeds."""
    panels = experiment.panels
    ncols = 2 if len(panels) > 1 else 1
    nrows = math.ceil(len(panels) / ncols)
    ticks = [str(r["config"]) if experiment.xlabel else str(r["label"]) for r in rows]
    slanted = max(len(t) for t in ticks) > 16  # long labels are slanted, and given room
    size = 1.2 if slanted else 1.0
    fig = Figure(figsize=(5 * ncols * size, 3.5 * nrows * size))  # no pyplot: no global state, no GUI backend
    axes = list(fig.subplots(nrows, ncols, squeeze=False).flat)
    x = list(range(len(rows)))
    for ax, panel in zip(axes, panels):
        width = 0.8 / len(panel.series)
        values = []
        for i, (stem, legend) in enumerate(panel.series):
            ceiling = min(panel.ceiling, ospa_cutoff) if stem.startswith("ospa") else panel.ceiling
            m, err = _series(rows, stem, panel.floor, ceiling)
            offset = (i - (len(panel.series) - 1) / 2) * width
            ax.bar([v + offset for v in x], m, width, yerr=err, capsize=3, label=legend, color=COLOURS.get(stem))
            values += m
        if len(panel.series) > 1:
            ax.legend(fontsize=8, ncol=2 if panel.log is False else 1)
            positive = all(v > 0 for v in values if not math.isnan(v))
            if panel.log or (panel.log is None and positive):
                ax.set_yscale("log")
            elif panel.ylabel.startswith("share"):  # room for the legend above the bars
                ax.set_ylim(0, 1.35)
        if all(math.isnan(v) for v in values):  # an empty axis from -0.05 to 0.05 said nothing
            ax.text(0.5, 0.5, panel.empty, transform=ax.transAxes, ha="center", va="center", fontsize=9,
                    color="0.3")
            ax.set_ylim(0, 1 if math.isfinite(panel.ceiling) else None)
        ax.set_title(panel.title)
        ax.set_ylabel(panel.ylabel)
        if slanted:
            ax.set_xticks(x, ticks, rotation=30, ha="right", fontsize=8)
        else:
            ax.set_xticks(x, ticks)
    for ax in axes[len(panels):]:  # an odd number of panels leaves a cell empty
        ax.set_visible(False)
    fig.suptitle(f"{experiment.description} (mean and 95% CI over trials)", fontsize=10)
    if experiment.xlabel:
        fig.supxlabel(experiment.xlabel, fontsize=9)
    fig.tight_layout()
    return fig


def write_figure(experiment, rows: list[dict[str, Any]], path: Path, ospa_cutoff: float = math.inf) -> Path:
    if experiment.figure_style == "lines":
        from trackjam.experiments.swarm_figure import swarm_figure

        swarm_figure(experiment, rows, ospa_cutoff).savefig(path, dpi=120)
    else:
        experiment_figure(experiment, rows, ospa_cutoff).savefig(path, dpi=120)
    return path
