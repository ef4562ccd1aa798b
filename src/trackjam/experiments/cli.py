"""What ``trackjam experiment NAME`` does once typer has parsed its options."""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path

from trackjam.errors import counted, printable
from trackjam.experiments.engine import run_experiment
from trackjam.experiments.definitions import get_experiment

OPTIONS = {
    "NAME": "table1 (Table I / Fig. 4), constraints (Fig. 5), or ours: solvers (GRASP vs exact), "
            "holding (track quality on Fig. 3), comms (message faults), swarm (K targets x N agents)",
    "--trials": "trials per configuration, the same draws for every configuration (paper: 20)",
    "--steps": "steps of dT = 1 s per trial (paper: 30)",
    "--seed": "experiment seed; trial k's draw and each (configuration, trial) seed derive from it",
    "--workers": "local worker processes (default: CPU count; 1 runs in this process)",
    "--scheduler": "address [SCHEME://]HOST:PORT (tcp, the default, tls, ws or wss) of a running Dask scheduler; trials run on its workers",
    "--out": "output folder (default runs/experiment-NAME); rerun with the same options to resume",
    "--set": "key=value scenario override applied to every configuration (repeatable)",
    "--grid": "swarm only: its cells, TARGETSxAGENTS, each side numbers or ranges (default 1-4x3-6)",
}


def experiment_command(
    name: str,
    trials: int = 20,
    steps: int = 30,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    out: Path | None = None,
    overrides: list[str] | None = None,
    grid: str | None = None,
) -> None:
    """Run or resume the experiment with a progress display, then print its summary table."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    result = run_experiment(
        name, trials=trials, steps=steps, seed=seed, workers=workers, scheduler=scheduler,
        out=out if out is not None else Path("runs") / f"experiment-{name}", overrides=overrides, grid=grid,
    )
    # escaped: rich read a [bracketed] part of the --out path as markup and dropped it
    summary = printable(str(result.out / "summary.csv"))
    table = Table(title=escape(f"{name}: mean {_pm()} 95% CI over trials ({summary})"))
    table.add_column("#", justify="right")
    table.add_column("configuration")
    table.add_column("trials", justify="right")
    experiment = get_experiment(name, grid)
    units = [_unit(key, description) for _, key, description in experiment.metrics]
    for (stem, _, _), unit in zip(experiment.metrics, units):
        table.add_column(escape(f"{stem} [{unit}]" if unit else stem), justify="right")
    for stem, _, _ in experiment.counts:
        table.add_column(stem, justify="right")
    table.add_column(escape("step [ms]"), justify="right")
    for row, timing in zip(result.summary, result.timing):
        cells = [_mean_ci(row[f"{s}_mean"], row[f"{s}_ci95"], 100.0 if unit == "%" else 1.0)
                 for (s, _, _), unit in zip(experiment.metrics, units)]
        cells += [f"{row[s]}/{row[f'{s}_of']}" for s, _, _ in experiment.counts]
        table.add_row(str(row["config"]), escape(row["label"]), str(row["trials"]), *cells,
                      f"{1000 * timing['step_s_mean']:.3g}")
    paired = None
    if result.paired and len(result.paired) <= MAX_PAIRS_SHOWN:
        # a count that applies to no trial (no hidden spell in the paper's draw) gets no column
        applying = tuple(c for c in experiment.counts if any(row[f"{c[0]}_of"] for row in result.summary))
        paired = paired_table(result, experiment.metrics, units, applying)
    console = Console(width=_wide_enough(table, *([paired] if paired is not None else [])))
    console.print(table)
    if paired is not None:
        console.print(paired)
    elif result.paired:
        print(f"{len(result.paired)} paired comparisons in {printable(str(result.out / 'paired.csv'))}")
    ran = f"ran {counted(result.ran, 'trial')}" if result.ran else "all trials were already in OUT"
    print(f"{ran}; wrote {', '.join(p.name for p in result.files)} to {printable(str(result.out))}")


MAX_PAIRS_SHOWN = 16  # more (the swarm grid's 36) stay in paired.csv


def _wide_enough(*tables) -> int:
    """The closing tables' width: 220 columns, or the least (in steps of 10) at which none of
    them cuts a word short with an ellipsis (at 220 the swarm experiment's 17 columns had cut
    'held_airborne' to 'held_airbor…' and 'configuration' to 'configurati…')."""
    import io

    from rich.console import Console

    widest = max(Console(width=100_000).measure(t).maximum for t in tables)
    width = 220
    while width < widest:
        out = io.StringIO()
        probe = Console(file=out, width=width, color_system=None)
        for t in tables:
            probe.print(t)
        if "…" not in out.getvalue():
            break
        width += 10
    return width


def paired_table(result, metrics, units, counts=()):
    """The paired comparisons as a table: per pair a -> b, each metric's mean over the trials of
    b - a with its 95 % interval, marked * where the interval leaves out 0 (significant); for
    each count, the trials b gained and lost against a, with the sign test's p (* below 0.05)."""
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=escape(f"paired, b - a: mean {_pm()} 95% CI over the same trials, * significant "
                               f"({printable(str(result.out / 'paired.csv'))})"))
    table.add_column("a -> b", justify="right")
    table.add_column("comparison")
    table.add_column("trials", justify="right")
    for (stem, _, _), unit in zip(metrics, units):
        table.add_column(escape(f"{stem} [{'points' if unit == '%' else unit}]" if unit else stem), justify="right")
    for stem, _, _ in counts:
        table.add_column(f"{stem} gained/lost (p)", justify="right")
    for row in result.paired:
        cells = []
        for (stem, _, _), unit in zip(metrics, units):
            diff, ci = row[f"{stem}_diff"], row[f"{stem}_ci95"]
            text = _mean_ci(diff, ci, 100.0 if unit == "%" else 1.0, signed=True)
            significant = diff is not None and ci is not None and math.isfinite(ci) and abs(diff) > ci
            cells.append(text + (" *" if significant else ""))
        for stem, _, _ in counts:
            p = row.get(f"{stem}_p")
            shown = "-" if p is None or not math.isfinite(p) else f"{p:.2g}" + (" *" if p < 0.05 else "")
            cells.append(f"{row[f'{stem}_gained']}/{row[f'{stem}_lost']} ({shown})")
        table.add_row(f"{row['a']} -> {row['b']}", escape(row["label"]), str(row["trials"]), *cells)
    return table


def _unit(key: str, description: str) -> str:
    """A metric's unit in the closing table: % for a share (printed as a percentage, as the
    README's tables show them), else the one its description names in brackets, if any."""
    if key.endswith("_share"):
        return "%"
    found = re.search(r"\[([^\]]+)\]", description)
    return found.group(1) if found else ""


def _mean_ci(mean, ci, scale: float = 1.0, signed: bool = False) -> str:
    """``mean ± ci`` (both times ``scale``; ``signed``: the mean with its sign, for a difference);
    one trial has no interval (it printed "± nan"), no value prints "-"."""
    if mean is None or not math.isfinite(mean):
        return "-"
    mean = mean * scale
    if ci is not None and math.isfinite(ci) and abs(mean) < 1e-9 * abs(ci * scale):
        mean = 0.0  # shares' rounding (6.9e-18 = 0.1 + 0.2 - 0.3 ...) had printed "+6.94e-16 ± 13"
    shown = f"{mean:+.3g}" if signed else f"{mean:.3g}"
    if ci is None or not math.isfinite(ci):
        return shown
    ci = ci * scale
    return f"{shown} {_pm()} {ci:.0f}" if ci >= 10 else f"{shown} {_pm()} {ci:.2g}"  # no 4.2e+02 for 420


def _pm() -> str:
    """"±", or "+-" where the standard output cannot encode it (an ASCII locale)."""
    try:
        "±".encode(sys.stdout.encoding or "ascii")
        return "±"
    except (UnicodeEncodeError, LookupError):
        return "+-"
