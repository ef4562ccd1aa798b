"""Figures laid out like the paper's Fig. 4 (per configuration of Table I) and Fig. 5
(constraints on/off): four panels of means with 95% confidence intervals, from summary.csv."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

# panel title, y label, [(column stem, legend)]
FIG4 = (
    ("(a) jamming incidents", "incidents per trial per agent", [("incidents", None)]),
    ("(b) received power", "W", [("target_received_w", "target"), ("agent_received_w", "agents")]),
    ("(c) transmit power", "W per agent per step", [("transmit_w", None)]),
    ("(d) tracking error", "OSPA [m]", [("ospa", None)]),
)
FIG5 = (
    ("(a) jamming incidents", "incidents per trial per agent", [("incidents", None)]),
    ("(b) agent received power", "W", [("agent_received_w", None)]),
    ("(c) target received power", "W", [("target_received_w", None)]),
    ("(d) tracking error", "OSPA [m]", [("ospa", None)]),
)


def _num(v: Any) -> float:
    if v is None or v == "":
        return math.nan
    return float(v)


def write_figure(experiment, rows: list[dict[str, Any]], path: Path) -> Path:
    """Four panels, one bar (with its CI as an error bar) per configuration and series."""
    panels = FIG5 if experiment.name == "constraints" else FIG4
    fig = Figure(figsize=(10, 7))  # no pyplot: no global state, no GUI backend
    axes = fig.subplots(2, 2)
    x = list(range(len(rows)))
    if experiment.name == "table1":
        ticks = [str(r["config"]) for r in rows]
        xlabel = "configuration (Table I): 1-4: 11 controls, 5-8: 79 controls; theta_a 60/80/100/120 deg"
    else:
        ticks = [str(r["label"]) for r in rows]
        xlabel = ""
    for ax, (title, ylabel, series) in zip(axes.flat, panels):
        width = 0.8 / len(series)
        values = []
        for i, (stem, legend) in enumerate(series):
            m = [_num(r[f"{stem}_mean"]) for r in rows]
            e = [0.0 if math.isnan(_num(r[f"{stem}_ci95"])) else _num(r[f"{stem}_ci95"]) for r in rows]
            offset = (i - (len(series) - 1) / 2) * width
            ax.bar([v + offset for v in x], m, width, yerr=e, capsize=3, label=legend)
            values += m
        if len(series) > 1:
            ax.legend()
            if all(v > 0 for v in values if not math.isnan(v)):
                ax.set_yscale("log")
        ax.set_title(title)
        ax.set_ylabel(ylabel)
        ax.set_xticks(x, ticks)
    fig.suptitle(f"{experiment.description} (mean and 95% CI over trials)", fontsize=10)
    if xlabel:
        fig.supxlabel(xlabel, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return path
