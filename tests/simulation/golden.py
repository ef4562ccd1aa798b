"""Golden logs: runs recorded before a refactoring, held bit for bit by test_golden.py.

A change that alters the model's behaviour on purpose re-records them in the same commit,
and says so in its message:  python tests/simulation/golden.py --record
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent / "golden"
TIMING = {"solve_s", "step_s"}  # wall times differ run to run

CASES = {
    "fig3-exact": ("paper-fig3", ["control.solver=exact"]),
    "fig3-grasp": ("paper-fig3", ["control.solver=grasp", "control.grasp.samples=300", "control.grasp.iterations=8",
                                  "control.grasp.threads=1"]),
    "fig3-greedy-aim": ("paper-fig3", ["control.solver=greedy", "antenna.pointing=aim"]),
    "literal-hover": ("paper-fig3-literal", ["control.solver=exact", "steps=12"]),
    "fig3-exact-mean-measurement": ("paper-fig3", ["control.solver=exact", "fusion.existence=mean",
                                                   "filter.birth=measurement", "steps=20"]),
}


def run_case(name: str) -> dict[str, np.ndarray]:
    from trackjam.config import load_scenario
    from trackjam import simulate

    preset, overrides = CASES[name]
    r = simulate(load_scenario(preset, overrides))
    out = {}
    for table, cols in (("steps", r.steps), ("agents", r.agents), ("meas", r.measurements)):
        for k, v in cols.items():
            if k not in TIMING:
                out[f"{table}/{k}"] = np.asarray(v)
    return out


def path(name: str) -> Path:
    return HERE / f"{name}.npz"


if __name__ == "__main__" and "--record" in sys.argv:
    HERE.mkdir(exist_ok=True)
    for name in CASES:
        np.savez_compressed(path(name), **run_case(name))
        print("recorded", path(name))
