"""`trackjam bench`: run the benchmarks, print a table per group, optionally write JSON."""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path


def machine() -> dict:
    import numba
    import numpy

    return {
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "numba": numba.__version__,
        "machine": platform.machine(),
    }


def _groups(quick: bool) -> dict:
    from trackjam.benchmarks import control, env, filter, run

    return {
        "filter": lambda: [{"name": "Bernoulli filter step", **filter.bench_filter_step(repeats=20 if quick else 200)}],
        "control": lambda: [{"name": k, **v} for k, v in control.run(quick=quick).items()],
        "run": lambda: [run.bench_run(solver, repeats=1 if quick else 3) for solver in ("exact", "grasp")],
        "env": lambda: [env.bench_env(episodes=1 if quick else 5)],
    }


def _print(group: str, rows: list[dict]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(width=140)
    console.rule(group)
    for row in rows:
        table = Table(title=str(row.get("name", group)), title_justify="left")
        table.add_column("figure")
        table.add_column("value", justify="right")
        for k, v in row.items():
            if k == "name" or isinstance(v, (list, dict)):
                continue
            table.add_row(k, f"{v:.4g}" if isinstance(v, float) else str(v))
        console.print(table)
        for k, v in row.items():
            if isinstance(v, list) and v and isinstance(v[0], dict):
                sub = Table(title=f"{group}: {k}", title_justify="left")
                for col in v[0]:
                    sub.add_column(str(col), justify="right")
                for r in v:
                    sub.add_row(*[f"{x:.4g}" if isinstance(x, float) else str(x) for x in r.values()])
                console.print(sub)


def run_benchmarks(quick: bool = False, json_out: Path | None = None, only: list[str] | None = None) -> dict:
    from trackjam.errors import ConfigError

    groups = _groups(quick)
    chosen = only or list(groups)
    unknown = [g for g in chosen if g not in groups]
    if unknown:
        raise ConfigError(f"--only {unknown[0]}: unknown benchmark group (choose from {', '.join(groups)})")
    results = {"machine": machine(), "quick": quick}
    print(f"machine: {results['machine']}", flush=True)
    for g in chosen:
        print(f"running {g} benchmarks...", flush=True)
        rows = groups[g]()
        results[g] = rows
        _print(g, rows)
    if json_out is not None:
        Path(json_out).write_text(json.dumps(results, indent=2) + "\n")
    return results
