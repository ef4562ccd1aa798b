"""Benchmark of whole runs: the paper's Fig. 3 scenario (and `swarm-3`, several targets), wall
time per step."""

from __future__ import annotations

import time

import numpy as np


def bench_run(solver: str, repeats: int = 3, steps: int | None = None, preset: str = "paper-fig3") -> dict:
    """Wall time of ``preset`` with ``solver`` (compilation warmed up by a first short run)."""
    from trackjam.simulation.build import build, load_scenario, with_seed
    from trackjam.simulation.loop import simulate

    overrides = [f"control.solver={solver}"]
    if steps is not None:
        overrides.append(f"steps={steps}")
    s = load_scenario(preset, overrides)
    c = build(s)
    simulate(load_scenario(preset, overrides + ["steps=3"]))  # compile and cache
    totals, per_step, solve = [], [], []
    for r in range(repeats):
        t0 = time.perf_counter()
        res = simulate(with_seed(s, c.seed + r))
        totals.append(time.perf_counter() - t0)
        per_step.append(float(np.mean(res.steps["step_s"])))
        solve.append(float(np.mean(res.steps["solve_s"])))
    return {
        "name": f"run {preset} ({solver})",
        "steps": c.steps,
        "repeats": repeats,
        "run_s_median": float(np.median(totals)),
        "step_ms_median": 1000 * float(np.median(per_step)),
        "solve_ms_median": 1000 * float(np.median(solve)),
    }
