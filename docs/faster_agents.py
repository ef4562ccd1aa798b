"""Faster agents and `control.close_in` (docs/holding.md, "Faster agents: a trap of the one-step
objective"): the preset `pursuit` with the paper's 5 m steps and with 7 m steps
(`agents.radial_steps: [1, 3, 5, 7]`), each with and without closing in, run seed by seed on the
same truths; then the paired table of the docs.

Run: python docs/faster_agents.py [FIRST LAST [VARIANT ...]]   (seeds, by default 1 300; every
         variant, or those named; 2 spawned workers; writes their rows into
         docs/experiments/faster/runs.csv, keeping the others)
     python docs/faster_agents.py table            (the two tables, from the committed runs)
     python docs/faster_agents.py figure           (docs/faster_agents.png, from the committed runs)"""

import csv
import multiprocessing as mp
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from trackjam.experiments.backends import one_numba_thread  # the pool's workers: one numba thread each
from trackjam.experiments.summary import count_ci95, mean_ci95, sign_test

HERE = Path(__file__).parent
RUNS = HERE / "experiments" / "faster" / "runs.csv"
FIGURE = HERE / "faster_agents.png"
SHOWN = ("5 m", "7 m", "7 m, close_in 0.05", "5 m, close_in 0.05")  # the figure's variants
FAST = [1, 3, 5, 7]
# (name, overrides of the preset); the first is the reference of the table
VARIANTS = {
    "5 m": {},
    "7 m": {"agents__radial_steps": FAST},
    "7 m, close_in 0.05": {"agents__radial_steps": FAST, "control__close_in": 0.05},
    "5 m, close_in 0.05": {"control__close_in": 0.05},
    "7 m, close_in 0.025": {"agents__radial_steps": FAST, "control__close_in": 0.025},
    "7 m, close_in 0.2": {"agents__radial_steps": FAST, "control__close_in": 0.2},
    "5 m, close_in 0.025": {"control__close_in": 0.025},
}
SEEDS = {"7 m, close_in 0.025": (1, 150), "7 m, close_in 0.2": (1, 150)}  # the threshold's check: fewer seeds
COLUMNS = ("seed", "variant", "held", "false_track", "reacquired", "ospa", "incidents", "closed_steps")
# (variant, against): the rows of the docs' table
PAIRS = (("7 m", "5 m"), ("7 m, close_in 0.05", "7 m"), ("7 m, close_in 0.05", "5 m"), ("5 m, close_in 0.05", "5 m"),
         ("7 m, close_in 0.025", "7 m, close_in 0.05"), ("7 m, close_in 0.2", "7 m, close_in 0.05"),
         ("5 m, close_in 0.025", "5 m"))


def one(job: tuple[int, str]) -> dict:
    """Variant ``job[1]`` of the preset on seed ``job[0]``: its run's summary, as one row."""
    from trackjam.config.loading import load_scenario
    from trackjam.simulation.loop import simulate

    seed, variant = job
    r = simulate(load_scenario("pursuit", seed=seed, **VARIANTS[variant]))
    s = r.summary
    return {"seed": seed, "variant": variant, "held": s["held_share"], "false_track": s["false_track_share"],
            "reacquired": bool(s["reacquired_after_last_spell"]), "ospa": s["ospa_mean"],
            "incidents": s["jamming_incidents_per_agent"], "closed_steps": int(np.sum(r.steps["closed_in"]))}


def read(path: Path = RUNS) -> dict[str, dict[int, dict]]:
    """variant -> seed -> row, from the committed runs."""
    out: dict[str, dict[int, dict]] = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            row = {"seed": int(r["seed"]), "variant": r["variant"], "held": float(r["held"]),
                   "false_track": float(r["false_track"]), "reacquired": r["reacquired"] == "True",
                   "ospa": float(r["ospa"]), "incidents": float(r["incidents"]), "closed_steps": int(r["closed_steps"])}
            out.setdefault(row["variant"], {})[row["seed"]] = row
    return out


def _t(x: np.ndarray, digits: int = 1) -> str:
    m, h = mean_ci95(x)
    return f"{m:+.{digits}f} ± {h:.{digits}f}"


def summary(runs: dict[str, dict[int, dict]]) -> list[str]:
    """One row per variant: held and false-track shares (mean ± 95 % t-interval), re-acquired,
    mean OSPA, steps closed in per run and jamming incidents per agent, over its seeds."""
    lines = ["| variant | seeds | held | false track | re-acquired | mean OSPA [m] | steps closed in per run | incidents per agent |",
             "|---|---|---|---|---|---|---|---|"]
    for v in VARIANTS:
        if v not in runs:
            continue
        rows = [runs[v][s] for s in sorted(runs[v])]
        held, false, ospa = (mean_ci95([scale * r[k] for r in rows]) for k, scale in
                             (("held", 100.0), ("false_track", 100.0), ("ospa", 1.0)))
        lines.append(f"| {v} | {rows[0]['seed']}-{rows[-1]['seed']} | {held[0]:.1f} ± {held[1]:.1f} % | "
                     f"{false[0]:.1f} ± {false[1]:.1f} % | {sum(r['reacquired'] for r in rows)} of {len(rows)} | "
                     f"{ospa[0]:.2f} ± {ospa[1]:.2f} | {np.mean([r['closed_steps'] for r in rows]):.1f} | "
                     f"{np.mean([r['incidents'] for r in rows]):.2f} |")
    return lines


def table(runs: dict[str, dict[int, dict]]) -> list[str]:
    """The docs' paired table: one row per pair, on the seeds both variants ran."""
    lines = ["| variant | against | seeds | held, points | false track, points | OSPA [m] | re-acquired, gained / lost (sign test) |",
             "|---|---|---|---|---|---|---|"]
    for a, b in PAIRS:
        seeds = sorted(set(runs.get(a, {})) & set(runs.get(b, {})))
        if not seeds:
            continue
        A, B = runs[a], runs[b]
        d = {k: np.array([A[s][k] - B[s][k] for s in seeds]) for k in ("held", "false_track", "ospa")}
        g, lost, p = sign_test((B[s]["reacquired"], A[s]["reacquired"]) for s in seeds)  # gained: A and not B
        n_a, n_b = (sum(R[s]["reacquired"] for s in seeds) for R in (A, B))
        lines.append(f"| {a} | {b} | {seeds[0]}-{seeds[-1]} | {_t(100 * d['held'])} | {_t(100 * d['false_track'])} | "
                     f"{_t(d['ospa'], 2)} | {n_a} against {n_b}: {g} / {lost} (p = {p:.2g}) |")
    return lines


def figure(runs: dict[str, dict[int, dict]], out: Path = FIGURE) -> Path:
    """Held share, re-acquisition and mean OSPA of the four main variants on their common seeds,
    each with its 95 % interval (t for the means, Clopper-Pearson for the re-acquisitions)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seeds = sorted(set.intersection(*(set(runs[v]) for v in SHOWN)))
    fig, axes = plt.subplots(1, 3, figsize=(11.0, 3.4), layout="constrained")
    y = np.arange(len(SHOWN))[::-1]
    colours = ["tab:gray", "tab:red", "tab:blue", "tab:olive"]
    for ax, key, label in zip(axes, ("held", "reacquired", "ospa"),
                              ("held (share of detectable steps)", "held again after the occlusion (share of seeds)",
                               "mean OSPA [m]")):
        for yi, v, c in zip(y, SHOWN, colours):
            x = [float(runs[v][s][key]) for s in seeds]
            if key == "reacquired":
                k, n, lo, hi = count_ci95(x)
                m = k / n
            else:
                m, h = mean_ci95(x)
                lo, hi = m - h, m + h
            ax.barh(yi, m, color=c, alpha=0.8)
            ax.errorbar(m, yi, xerr=[[m - lo], [hi - m]], color="black", capsize=3, lw=1)
        ax.set_xlabel(label, fontsize=9)
        ax.set_yticks(y, SHOWN if ax is axes[0] else [""] * len(SHOWN), fontsize=9)
    fig.suptitle(f"The preset `pursuit` with 5 m and 7 m steps, with and without control.close_in "
                 f"(seeds {seeds[0]}-{seeds[-1]}, 95 % intervals)", fontsize=10)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(first: int, last: int, variants: list[str] | None = None) -> None:
    """Run every variant (or those named) on seeds ``first``..``last`` (within its own seed range)
    and write them into the runs file, in place of those runs' earlier rows; the others are kept."""
    unknown = sorted(set(variants or ()) - set(VARIANTS))
    if unknown:
        sys.exit(f"unknown variant(s) {unknown}; expected some of {list(VARIANTS)}")
    jobs = [(s, v) for v in (variants or VARIANTS) for s in range(max(first, SEEDS.get(v, (first, last))[0]),
                                                    min(last, SEEDS.get(v, (first, last))[1]) + 1)]
    runs = read() if RUNS.exists() else {}
    with ProcessPoolExecutor(2, mp_context=mp.get_context("spawn"), initializer=one_numba_thread) as pool:
        for k, row in enumerate(pool.map(one, jobs), start=1):
            runs.setdefault(row["variant"], {})[row["seed"]] = row
            print(f"{k}/{len(jobs)} {row['variant']} seed {row['seed']}: held {row['held']:.3f}", flush=True)
    RUNS.parent.mkdir(parents=True, exist_ok=True)
    partial = RUNS.with_suffix(".partial")
    with open(partial, "w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS)
        w.writeheader()
        for v in VARIANTS:
            w.writerows(runs.get(v, {})[s] for s in sorted(runs.get(v, {})))
    partial.replace(RUNS)
    runs = read()  # as written, so the tables are those a later `table` prints
    print("\n".join(summary(runs) + [""] + table(runs)))
    print(figure(runs))


if __name__ == "__main__":
    if sys.argv[1:2] == ["table"]:
        runs = read()
        print("\n".join(summary(runs) + [""] + table(runs)))
    elif sys.argv[1:2] == ["figure"]:
        print(figure(read()))
    else:
        main(*(map(int, sys.argv[1:3]) if len(sys.argv) > 2 else (1, 300)), sys.argv[3:] or None)
