"""swarm-3 over many seeds: each target's held share of its detectable steps, the clairvoyant
ceiling's, and whether any exact search stopped at the preset's node budget (docs/swarm.md,
"The velocity cue on swarm-3"; README, Several targets).

    python docs/swarm_seeds.py [FIRST LAST] [--workers W]   # seeds FIRST..LAST, default 1 400

writes docs/experiments/swarm-seeds/seeds.csv (one row per seed) and prints the means with their
95 % t-intervals. Each run is `trackjam.simulate(load_scenario("swarm-3", ["seed=S"]))`; the
preset's `control.node_limit` makes every run repeat exactly on any machine under any load.
"""

from __future__ import annotations

import csv
import multiprocessing
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

OUT = Path(__file__).parent / "experiments" / "swarm-seeds" / "seeds.csv"
FIELDS = ["seed", "held_a", "held_b", "held_c", "ceiling_a", "ceiling_b", "ceiling_c", "capped_steps"]


def one(seed: int) -> dict:
    """One run's row: each target's held and ceiling shares, and the steps whose search the
    node budget stopped (not proven optimal, the team not hovering)."""
    import numpy as np

    import trackjam
    from trackjam.simulation.build import load_scenario

    r = trackjam.simulate(load_scenario("swarm-3", [f"seed={seed}"]))
    s, steps = r.summary, r.steps
    capped = int(np.sum(~np.asarray(steps["optimal"], dtype=bool) & (np.asarray(steps["mode"]) != "hover")))
    held, ceiling = s["held_share"], s["ceiling_share"]
    return {"seed": seed, **{f"held_{k}": held[i] for i, k in enumerate("abc")},
            **{f"ceiling_{k}": ceiling[i] for i, k in enumerate("abc")}, "capped_steps": capped}


def interval(x) -> tuple[float, float]:
    """Mean and half-width of its 95 % t-interval, in percent."""
    import numpy as np
    from scipy import stats

    x = 100 * np.asarray(x, dtype=float)
    return float(x.mean()), float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size))


def main(argv: list[str]) -> None:
    workers = 2
    if "--workers" in argv:
        i = argv.index("--workers")
        workers = int(argv[i + 1])
        argv = argv[:i] + argv[i + 2:]
    first, last = (int(argv[0]), int(argv[1])) if argv else (1, 400)
    os.environ["NUMBA_NUM_THREADS"] = "1"  # one thread per worker (spawned workers inherit it)
    seeds = range(first, last + 1)
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        rows = []
        for row in pool.map(one, seeds):
            rows.append(row)
            print(f"seed {row['seed']}: held a {row['held_a']:.2f} b {row['held_b']:.2f} c {row['held_c']:.2f}",
                  flush=True)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    with open(OUT, "w", newline="") as f:
        w = csv.DictWriter(f, FIELDS)
        w.writeheader()
        w.writerows(rows)
    for k in "abc":
        m, h = interval([r[f"held_{k}"] for r in rows])
        half = sum(r[f"held_{k}"] >= 0.5 for r in rows)
        print(f"held {k}: {m:.1f} ± {h:.1f} %, >= 50 % in {half} of {len(rows)} seeds")
    print("all three >= 50 %:", sum(all(r[f"held_{k}"] >= 0.5 for k in "abc") for r in rows),
          "; the ceiling:", sum(all(r[f"ceiling_{k}"] >= 0.5 for k in "abc") for r in rows))
    print("seeds with a search stopped by the node budget:", sum(r["capped_steps"] > 0 for r in rows))


if __name__ == "__main__":
    main(sys.argv[1:])
