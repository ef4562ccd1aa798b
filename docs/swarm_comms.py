"""The comms faults on `swarm-3` (docs/several-targets.md, "The comms faults with several
targets"): the preset with every message delivered, with 20 % and 50 % of the messages lost,
with every message one step late, and with agent 2 breaking down at step 11, run seed by seed
on the same truths; the held share of each target's detectable steps, over all targets, and the
mean OSPA, each fault paired against the faultless run (mean and 95 % t-interval of the
differences; "n.s." where the interval covers 0).

`swarm-3` bounds every exact search by a count of nodes (`control.node_limit`), so each run
repeats exactly on any machine under any load.

Run: python docs/swarm_comms.py [SEEDS]   (seeds 1..SEEDS, by default 20; one process, about
         11 minutes of CPU at 20). Writes each run's figures to
         docs/experiments/swarm-comms/runs.csv and prints the page's table, which
         tests/test_swarm_doc_results.py holds to that file."""

import csv
import sys
from pathlib import Path

import numpy as np
from scipy import stats

import trackjam
from trackjam import load_scenario

VARIANTS = {  # the first is the reference of the pairs
    "every message": [],
    "loss 0.2": ["comms.loss=0.2"],
    "loss 0.5": ["comms.loss=0.5"],
    "delay 1 step": ["comms.delay_steps=1"],
    "agent 2 breaks down at step 11": ["comms.failures=[{agent: 2, step: 11, mode: breakdown}]"],
}
COLUMNS = ("held a", "held b", "held c", "held, all", "OSPA")
OUT = Path(__file__).parent / "experiments" / "swarm-comms" / "runs.csv"


def figures(overrides: list[str], seed: int) -> list[float]:
    """Held shares per target and over all [%], then the mean OSPA [m], of one run."""
    s = trackjam.simulate(load_scenario("swarm-3", [*overrides, f"seed={seed}"])).summary
    return [100.0 * v for v in s["held_share"]] + [100.0 * s["held_share_total"], s["ospa_mean"]]


def ci95(x: np.ndarray) -> tuple[float, float]:
    return float(x.mean()), float(stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x)))


def table(runs: dict[str, np.ndarray]) -> list[str]:
    """The page's table, one line a fault, from each fault's figures seed by seed (rows in seed
    order, the columns of COLUMNS)."""
    ref = runs["every message"]
    n_seeds = len(ref)
    lines = [f"| fault (seeds 1-{n_seeds}) | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    for name, x in runs.items():
        cells = []
        for i, col in enumerate(COLUMNS):
            unit = " m" if col == "OSPA" else " %"
            m, h = ci95(x[:, i])
            cell = f"{m:.1f} ± {h:.1f}{unit}"
            if x is not ref:
                d, dh = ci95(x[:, i] - ref[:, i])
                cell += f" ({d:+.1f} ± {dh:.1f}{'' if abs(d) > dh else ', n.s.'})"
            cells.append(cell)
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def read_runs(path: Path = OUT) -> dict[str, np.ndarray]:
    """The figures ``main`` wrote, by fault, rows in seed order."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {name: np.array([[float(r[c]) for c in COLUMNS] for r in sorted((r for r in rows if r["fault"] == name),
                                                                            key=lambda r: int(r["seed"]))])
            for name in VARIANTS}


def main(n_seeds: int) -> None:
    runs = {name: np.array([figures(sets, seed) for seed in range(1, n_seeds + 1)]) for name, sets in VARIANTS.items()}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    with open(OUT, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["fault", "seed", *COLUMNS])
        for name, x in runs.items():
            for seed, row in enumerate(x, start=1):
                w.writerow([name, seed, *(repr(float(v)) for v in row)])
    print("\n".join(table(runs)))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
