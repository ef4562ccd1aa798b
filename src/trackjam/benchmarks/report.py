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


CALIBRATION = "numpy sort of 1,000,000 float64 (seed 0), median of 7"


def calibration_ms(repeats: int = 7) -> float:
    """Median wall time [ms] of a fixed single-threaded workload (``CALIBRATION``), timed at the
    start and the end of a bench run: a difference between the two says the machine's speed
    changed during the run (shared hosts drift). Dividing a row by its run's calibration is a
    rough guide for comparing two machines, not a measurement (README, Benchmarks)."""
    import time

    import numpy as np

    x = np.random.default_rng(0).random(1_000_000)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.sort(x, kind="quicksort")
        times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times))


def _groups(quick: bool) -> dict:
    from trackjam.benchmarks import control, env, filter, lmb, run

    return {
        "filter": lambda: [{"name": "Bernoulli filter step", **filter.bench_filter_step(repeats=20 if quick else 200)},
                           {"name": "Bernoulli filter step, estimate at the mode (filter.mode 5 m, 0.2)",
                            **filter.bench_filter_step(repeats=20 if quick else 200, mode=(5.0, 0.2))},
                           {"name": "Bernoulli filter step, resampling of a new track (filter.reserve_memory 1, "
                                    "filter.velocity_jitter 0.5)",
                            **filter.bench_filter_step(repeats=20 if quick else 200, resampling=(1, 0.5))},
                           {"name": "Bernoulli filter step, hidden-target mode (filter.visibility 0.05, 0.25)",
                            **filter.bench_filter_step(repeats=20 if quick else 200, visibility=(0.05, 0.25, False))},
                           {"name": "Bernoulli filter step, hidden-target mode per particle "
                                    "(filter.visibility 0.05, 0.25, per_particle)",
                            **filter.bench_filter_step(repeats=20 if quick else 200, visibility=(0.05, 0.25, True))},
                           {"name": "LMB filter step, 3 targets", **lmb.bench_lmb_step(repeats=5 if quick else 100)}],
        "control": lambda: [{"name": k, **v} for k, v in control.run(quick=quick).items()],
        "run": lambda: [*(run.bench_run(solver, repeats=1 if quick else 3) for solver in ("exact", "grasp")),
                        run.bench_run("exact", repeats=1, steps=5 if quick else None, preset="swarm-3")],
        "env": lambda: [env.bench_env(episodes=1 if quick else 5),
                        env.bench_env(episodes=1 if quick else 3, preset="swarm-3")],
    }


def flatten(d: dict, prefix: str = "") -> dict:
    """Nested dicts as one level, keys joined by dots (``{"solve": {"median_ms": 1}}`` ->
    ``{"solve.median_ms": 1}``); lists are kept as they are."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


def cell(v) -> str:
    """A value as the tables show it: 4 significant digits, yes/no, "-" for nothing."""
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _tables(group: str, rows: list[dict]) -> list:
    """One two-column table per benchmark (every scalar it measured, nested ones flattened),
    and one table per list of records in it (a column per key any record has). Every text is
    escaped: rich read the ``[env]`` of a skipped benchmark's ``pip install "trackjam[env]"`` as
    markup and dropped it."""
    from rich.markup import escape
    from rich.table import Table

    tables = []
    for row in rows:
        flat = flatten(row)
        name = str(flat.pop("name", group))
        table = Table(title=escape(name), title_justify="left")
        table.add_column("figure")
        table.add_column("value", justify="right")
        for k, v in flat.items():
            if not isinstance(v, list):
                table.add_row(escape(k), escape(cell(v)))
        tables.append(table)
        for k, v in flat.items():
            if isinstance(v, list) and v and all(isinstance(r, dict) for r in v):
                records = [flatten(r) for r in v]
                columns = list(dict.fromkeys(c for r in records for c in r))
                sub = Table(title=escape(f"{name}: {k}"), title_justify="left")
                for c in columns:
                    sub.add_column(escape(c), justify="right")
                for r in records:
                    sub.add_row(*[escape(cell(r.get(c))) for c in columns])
                tables.append(sub)
    return tables


def _print(group: str, rows: list[dict]) -> None:
    from rich.console import Console
    from rich.markup import escape

    console = Console(width=160)
    console.rule(escape(group))
    for table in _tables(group, rows):
        console.print(table)


def _earlier_figures(path: Path) -> bool:
    """``path`` holds what ``--json`` wrote before (a JSON object with the machine), which a new
    run may replace."""
    try:
        if path.stat().st_size > 10_000_000:
            return False
        data = json.loads(path.read_bytes())
    except (OSError, ValueError, RecursionError):  # RecursionError: [[[[... nested too deep to parse
        return False
    return isinstance(data, dict) and {"machine", "quick"} <= set(data)


def run_benchmarks(quick: bool = False, json_out: Path | None = None, only: list[str] | None = None) -> dict:
    from trackjam.errors import ConfigError
    from trackjam.files import check_writable, special_file

    groups = _groups(quick)
    chosen = only or list(groups)
    unknown = [g for g in chosen if g not in groups]
    if unknown:
        raise ConfigError(f"--only {unknown[0]}: unknown benchmark group (choose from {', '.join(groups)})")
    if json_out is not None:  # checked before minutes of benchmarks, not after
        json_out = Path(json_out)
        if json_out.is_dir():
            raise ConfigError(f"--json {json_out}: is a folder, not a file")
        if special_file(json_out):
            raise ConfigError(f"--json {json_out}: is not a regular file (a device or a pipe); choose a file name")
        if json_out.is_file() and not _earlier_figures(json_out):  # a run's summary.json was overwritten
            raise ConfigError(f"--json {json_out}: exists and is not an earlier `trackjam bench --json` file; "
                              "choose another name")
        if not json_out.absolute().parent.is_dir():
            parent = json_out.absolute().parent
            what = "is a file, not a folder" if parent.exists() else "is not an existing folder"
            raise ConfigError(f"--json {json_out}: {parent} {what}")
        check_writable(json_out.absolute().parent, f"--json {json_out}")
    results = {"machine": machine(), "quick": quick}
    print(f"machine: {results['machine']}", flush=True)
    start = calibration_ms()
    print(f"calibration ({CALIBRATION}): {start:.1f} ms", flush=True)
    for g in chosen:
        print(f"running {g} benchmarks...", flush=True)
        rows = groups[g]()
        results[g] = rows
        _print(g, rows)
    end = calibration_ms()
    results["calibration"] = {"workload": CALIBRATION, "start_ms": start, "end_ms": end}
    print(f"calibration at the end: {end:.1f} ms (at the start {start:.1f} ms; "
          "a drift between the two means the machine's speed changed during the run)", flush=True)
    if json_out is not None:
        from trackjam.errors import OutputError
        from trackjam.files import atomic_write

        try:
            atomic_write(json_out, lambda tmp: tmp.write_text(json.dumps(results, indent=2) + "\n"))
        except OSError as err:
            raise OutputError(f"--json {json_out}: cannot be written ({err.strerror or err}); the tables above hold the figures") from None
    return results
