"""Is the team on the target but silent? Runs the preset `pursuit` and logs, at every step, the
team's fused estimate whether it was reported or not, then scores the logs again as if the team
reported at other thresholds of P(the target exists and is visible) (docs/holding.md, "On the
target but silent: the report rule's threshold").

The report changes nothing the team does (its plans and filters never read it), so the scoring
is exact: at the preset's threshold, 0.5, it gives every run's own held steps and re-acquisition
(``tests/test_docs.py`` holds it to that). A step is reported when the fused existence is above
0.5, P(exists and visible) above the threshold and the position spread at most
``fusion.report_spread``; held, false track and re-acquisition are then those of
``trackjam.metrics.track_quality``, and the OSPA ``trackjam.metrics.ospa``'s (c = 10).

Run: python docs/report_threshold.py [FIRST LAST]   (seeds, by default 1 450; 2 spawned workers;
                                                     writes docs/experiments/report/steps.csv.gz)
     python docs/report_threshold.py table [FIRST LAST]   (the table, from the committed log)"""

import csv
import gzip
import multiprocessing as mp
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from trackjam.experiments.backends import one_numba_thread  # the pool's workers: one numba thread each

HERE = Path(__file__).parent
LOG = HERE / "experiments" / "report" / "steps.csv.gz"
COLUMNS = ("seed", "t", "detectable", "reported", "error_m", "existence", "seen", "spread_m")
THRESHOLDS = (0.5, 0.45, 0.4, 0.35, 0.3, 0.25)
CONFIRM, CUTOFF, SPREAD = 0.5, 10.0, 8.0  # the fused existence to report, OSPA's c [m], fusion.report_spread [m]


def one(seed: int, **overrides) -> tuple[list[dict], dict]:
    """The preset's run of ``seed``: one row per step, with the team's fused estimate's error (NaN
    without an estimate or a target), existence, P(exists and visible) and position spread, and
    whether it was reported; and the run's own summary."""
    from trackjam.config.loading import load_scenario
    from trackjam.control.planning import position_spread
    from trackjam.simulation.engine import Simulation, seen

    sim = Simulation(load_scenario("pursuit", seed=seed, **overrides))
    rows = []
    while not sim.done:
        record = sim.step()
        step, fused, truth = record.step, record.fused, record.step["truth"]
        held = fused is not None and fused.mean is not None
        rows.append({"seed": seed, "t": step["t"], "detectable": bool(step["target_detectable"]),
                     "reported": step["estimate"] is not None,
                     "error_m": float(np.linalg.norm(fused.mean[:3] - truth)) if held and truth is not None else np.nan,
                     "existence": float(fused.existence) if held else np.nan,
                     "seen": float(seen(fused)) if held else 0.0,
                     "spread_m": float(position_spread(fused.cov)) if held else np.inf})
    return rows, sim.result().summary


def score(rows: list[dict], threshold: float) -> dict:
    """One seed's logs (one row per step, in order) scored as if the team reported above
    ``threshold``: held and false-track shares of the detectable steps, whether it held the target
    after the last hidden spell, and the mean OSPA."""
    from trackjam.metrics.ospa import ospa
    from trackjam.metrics.track_quality import track_quality

    n = len(rows)
    detectable = np.array([r["detectable"] for r in rows])
    error = np.array([r["error_m"] for r in rows])
    report = np.array([r["existence"] > CONFIRM and r["seen"] > threshold and r["spread_m"] <= SPREAD for r in rows])
    # the classes and the OSPA need only the distance: the truth at the origin, a report at its error along x
    zeros, nan = np.zeros(n), np.full(n, np.nan)
    est_x = np.where(report, error, np.nan)
    existence = np.array([r["existence"] for r in rows])
    q = track_quality({"target_detectable": detectable, "truth_x": zeros, "truth_y": zeros, "truth_z": zeros,
                       "est_x": est_x, "est_y": np.where(report, 0.0, nan), "est_z": np.where(report, 0.0, nan),
                       "existence": existence})
    errors = [ospa(np.zeros(3) if d else None, np.array([e, 0.0, 0.0]) if r else None, c=CUTOFF)
              for d, r, e in zip(detectable, report, error)]
    return {"held": q["held_share"], "false_track": q["false_track_share"],
            "reacquired": bool(q["reacquired_after_last_spell"]), "ospa": float(np.mean(errors))}


def read_log(first: int, last: int) -> dict[int, list[dict]]:
    rows: dict[int, list[dict]] = {}
    with gzip.open(LOG, "rt", newline="") as f:
        for r in csv.DictReader(f):
            seed = int(r["seed"])
            if first <= seed <= last:
                rows.setdefault(seed, []).append(
                    {"seed": seed, "t": int(r["t"]), "detectable": r["detectable"] == "True",
                     "reported": r["reported"] == "True", **{k: float(r[k]) for k in COLUMNS[4:]}})
    return rows


def table(rows: dict[int, list[dict]]) -> list[str]:
    """Markdown rows: each threshold paired against 0.5 over the seeds (mean ± 95 % t-interval)."""
    from trackjam.experiments.summary import mean_ci95

    seeds = sorted(rows)
    scored = {th: [score(sorted(rows[s], key=lambda r: r["t"]), th) for s in seeds] for th in THRESHOLDS}

    def arr(th, key):
        return np.array([float(x[key]) for x in scored[th]])

    def paired(th, key, scale):
        mean, half = mean_ci95((arr(th, key) - arr(0.5, key)) * scale)
        return f"{mean:+.2f} ± {half:.2f}" if scale == 100 else f"{mean:+.3f} ± {half:.3f}"

    out = [f"seeds {seeds[0]}-{seeds[-1]}",
           "| report while P(exists and visible) > | held | false track | re-acquired | mean OSPA [m] |",
           "|---|---|---|---|---|"]
    for th in THRESHOLDS:
        n_re = int(arr(th, "reacquired").sum())
        if th == 0.5:
            out.append(f"| 0.5 (the preset) | {100 * arr(th, 'held').mean():.1f} % | "
                       f"{100 * arr(th, 'false_track').mean():.1f} % | {n_re} of {len(seeds)} | {arr(th, 'ospa').mean():.2f} |")
        else:
            out.append(f"| {th} | {paired(th, 'held', 100)} | {paired(th, 'false_track', 100)} | {n_re} | "
                       f"{paired(th, 'ospa', 1)} |")
    return out


def main(argv: list[str]) -> None:
    if argv[:1] == ["table"]:
        first, last = (int(a) for a in argv[1:3]) if len(argv) >= 3 else (1, 450)
        print("\n".join(table(read_log(first, last))))
        return
    first, last = (int(a) for a in argv[:2]) if len(argv) >= 2 else (1, 450)
    LOG.parent.mkdir(parents=True, exist_ok=True)
    tmp = LOG.with_suffix(".part")
    with ProcessPoolExecutor(2, mp_context=mp.get_context("spawn"), initializer=one_numba_thread) as pool, \
            gzip.open(tmp, "wt", newline="") as f:
        w = csv.DictWriter(f, COLUMNS)
        w.writeheader()
        for seed, (rows, _) in zip(range(first, last + 1), pool.map(one, range(first, last + 1))):
            w.writerows({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()} for r in rows)
            print(f"seed {seed}: {len(rows)} steps", flush=True)
    tmp.replace(LOG)
    print("\n".join(table(read_log(first, last))))


if __name__ == "__main__":
    main(sys.argv[1:])
