"""The swarm experiment's figure: each panel's metric against the number of targets K, one line
per team size N with its 95 % interval as a band (a panel's further series, the ceiling, dashed),
and the K = 1 cells of the one-target engine as hollow markers with their intervals beside K = 1.

A band is clipped at the panel's floor (no negative shares, metres or steps), a share's at 1 and
an OSPA's at its cut-off c.
"""

from __future__ import annotations

import math
from typing import Any

from matplotlib.figure import Figure

from trackjam.experiments.figures import _num


def _cells(rows: list[dict[str, Any]], engine: str) -> dict[int, list[dict[str, Any]]]:
    """The rows of ``engine`` by team size N, each list in order of K."""
    out: dict[int, list[dict[str, Any]]] = {}
    for r in rows:
        if r["engine"] == engine:
            out.setdefault(int(r["agents"]), []).append(r)
    return {n: sorted(rs, key=lambda r: int(r["targets"])) for n, rs in sorted(out.items())}


def band(means: list[float], ci95: list[float], floor: float, ceiling: float = math.inf) -> tuple[list[float], list[float]]:
    """(low, high) of each interval mean +- ci95, cut at ``floor`` and ``ceiling`` (a NaN
    half-width, one trial, gives the mean itself)."""
    low, high = [], []
    for m, e in zip(means, ci95):
        e = 0.0 if math.isnan(e) else e
        low.append(max(m - e, floor))
        high.append(min(m + e, ceiling))
    return low, high


def swarm_figure(experiment, rows: list[dict[str, Any]], ospa_cutoff: float = math.inf) -> Figure:
    """The figure of the swarm ``experiment`` (its ``panels``, one stem each) over summary rows;
    an OSPA band stops at ``ospa_cutoff``, the c no OSPA exceeds."""
    panels = experiment.panels
    ncols = 3 if len(panels) > 4 else 2
    nrows = math.ceil(len(panels) / ncols)
    fig = Figure(figsize=(4.6 * ncols, 3.4 * nrows))  # no pyplot: no global state, no GUI backend
    axes = list(fig.subplots(nrows, ncols, squeeze=False).flat)
    swarm, reference = _cells(rows, "swarm"), _cells(rows, "one-target")
    colours = {n: f"C{i}" for i, n in enumerate(swarm | reference)}
    ks = sorted({int(r["targets"]) for r in rows})
    for ax, panel in zip(axes, panels):
        stem = panel.series[0][0]
        share = panel.ylabel.startswith("share")
        ceiling = 1.0 if share else ospa_cutoff if stem.startswith("ospa") else math.inf
        for n, cells in swarm.items():
            x = [int(r["targets"]) for r in cells]
            m = [_num(r[f"{stem}_mean"]) for r in cells]
            low, high = band(m, [_num(r[f"{stem}_ci95"]) for r in cells], panel.floor, ceiling)
            ax.plot(x, m, "o-", color=colours[n], label=f"N = {n}")
            ax.fill_between(x, low, high, color=colours[n], alpha=0.15, linewidth=0)
            for reference_stem, _ in panel.series[1:]:  # a reference (the ceiling): dashed, no band
                ax.plot(x, [_num(r[f"{reference_stem}_mean"]) for r in cells], "--", color=colours[n], linewidth=1)
        for i, (n, cells) in enumerate(reference.items()):
            m = [_num(r[f"{stem}_mean"]) for r in cells]
            low, high = band(m, [_num(r[f"{stem}_ci95"]) for r in cells], panel.floor, ceiling)
            x = [1.0 + 0.06 * (i + 1)] * len(cells)
            err = [[mi - lo for mi, lo in zip(m, low)], [hi - mi for mi, hi in zip(m, high)]]
            ax.errorbar(x, m, yerr=err, fmt="o", mfc="white", color=colours[n], capsize=2,
                        label="one-target engine" if i == 0 else None)
        ax.set_title(panel.title, fontsize=10)
        # the references' key, in the legend
        keys = [ax.plot([], [], "--", color="0.4", linewidth=1, label=label)[0] for _, label in panel.series[1:]]
        if ax is not axes[0] and keys:
            ax.legend(fontsize=7, handles=keys, loc="lower left")
        ax.set_ylabel(panel.ylabel)
        ax.set_xlabel("targets K")
        ax.set_xticks(ks)
        if share:
            ax.set_ylim(-0.02, 1.05)
    axes[0].legend(fontsize=8)
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    fig.suptitle(f"{experiment.description} (mean and 95% CI over trials)", fontsize=10)
    fig.tight_layout()
    return fig
