"""The comms faults on `swarm-3` (docs/several-targets.md, "The comms faults with several
targets"): the preset with every message delivered, with 20 % and 50 % of the messages lost,
with every message one step late, and with agent 2 breaking down at step 11, run seed by seed
on the same truths; the held share of each target's detectable steps, over all targets, and the
mean OSPA, each fault paired against the faultless run (mean and 95 % t-interval of the
differences; "n.s." where the interval covers 0).

`swarm-3` sets no `control.node_limit`: the exact solver's 1 s of wall time can bind under load,
so a seed's run can differ from one machine or load to another.

Run: python docs/swarm_comms.py [SEEDS]   (seeds 1..SEEDS, by default 20; one process, about
         11 minutes of CPU at 20)"""

import sys

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


def figures(overrides: list[str], seed: int) -> list[float]:
    """Held shares per target and over all [%], then the mean OSPA [m], of one run."""
    s = trackjam.simulate(load_scenario("swarm-3", [*overrides, f"seed={seed}"])).summary
    return [100.0 * v for v in s["held_share"]] + [100.0 * s["held_share_total"], s["ospa_mean"]]


def ci95(x: np.ndarray) -> tuple[float, float]:
    return float(x.mean()), float(stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x)))


def main(n_seeds: int) -> None:
    runs = {name: np.array([figures(sets, seed) for seed in range(1, n_seeds + 1)]) for name, sets in VARIANTS.items()}
    ref = runs["every message"]
    print(f"| fault (seeds 1-{n_seeds}) | " + " | ".join(COLUMNS) + " |")
    print("|---" * (len(COLUMNS) + 1) + "|")
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
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
