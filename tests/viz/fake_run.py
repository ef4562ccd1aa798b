"""A small synthetic run whose every log column is consistent with the radio model.

The visualisation only reads logs, so its tests do not need the simulation loop: this builds
the two tables of a run (``steps``: one row per step, ``agents``: one row per (step, agent))
from a scripted target and scripted agent moves and levels, with every power, detection
probability and jamming flag computed by :mod:`trackjam.radio.antenna` exactly as the loop
computes them. The target is occluded at step 3 and gone at step 5, so every panel has
something to show.
"""

from __future__ import annotations

import numpy as np

from trackjam.config import Scenario, validate_scenario
from trackjam.simulation.build import antenna_model
from trackjam.radio.antenna import (
    detection_probability,
    interference_matrix,
    received_power,
)

FAKE_STEPS = 5


def fake_scenario(steps: int = FAKE_STEPS) -> Scenario:
    """The paper's Fig. 3 geometry, shortened; occluded at step 3, gone after step 4."""
    return validate_scenario(
        {
            "name": "fake-run",
            "steps": steps,
            "target": {"initial": [20, 20, 20, 1.5, 2.0, 1.7], "occlusions": [[3, 3]], "disappears": steps - 1},
            "agents": {"initial": [[30, 30, 30], [20, 10, 10], [10, 15, 15]]},
        }
    )


def fake_run(scenario: Scenario | None = None, seed: int = 7) -> tuple[dict, dict, Scenario]:
    """``(steps, agents, scenario)``: column dicts of 1-D numpy arrays, as read from Parquet."""
    s = scenario or fake_scenario()
    rng = np.random.default_rng(seed)
    ant = antenna_model(s)
    T, N = s.steps, s.n_agents
    lo, hi = np.asarray(s.area.low), np.asarray(s.area.high)
    c = s.metrics.ospa_cutoff
    occluded = {t for a, b in s.target.occlusions for t in range(a, b + 1)}

    x0 = np.asarray(s.target.initial, dtype=float)
    u = np.asarray(s.agents.initial, dtype=float)
    aim = x0[:3].copy()
    steps: dict[str, list] = {k: [] for k in STEP_COLUMNS}
    agents: dict[str, list] = {k: [] for k in AGENT_COLUMNS}
    for t in range(1, T + 1):
        exists = s.target.appears <= t <= (s.target.disappears or T)
        detectable = exists and t not in occluded
        truth = x0[:3] + (t - 1) * x0[3:] if exists else np.full(3, np.nan)

        u_prev = u.copy()
        u = np.clip(u + rng.normal(0.0, 2.0, size=(N, 3)), lo, hi)
        level_index = (np.arange(N) + t) % len(ant.levels_w)
        power_w = ant.levels_w[level_index]
        point = np.repeat((truth if exists else aim)[None, :], N, axis=0)
        R = interference_matrix(u, point, power_w, ant)
        interference_w = R.sum(axis=1)
        if exists:
            p_d = detection_probability(truth, u, point, power_w, ant)
            to_target_w = received_power(truth, u, point, power_w, ant)
        else:
            p_d = np.zeros(N)
            to_target_w = np.zeros(N)
        p_d_seen = p_d if detectable else np.zeros(N)
        detected = rng.random(N) < p_d_seen
        # existence follows the script: high while detectable, low while occluded, and a
        # false track (e > 0.5 without a target) at the last step
        base = 0.85 if detectable else (0.6 if not exists else 0.3)
        own_e = np.clip(base + 0.05 * detected + rng.normal(0, 0.03, N), 0.01, 0.99)
        e = float(own_e.mean())
        est = truth + rng.normal(0, 1.0, 3) if (e > 0.5 and exists) else (
            aim + 5.0 if e > 0.5 else np.full(3, np.nan)
        )
        ospa = _ospa(truth if exists else None, est if e > 0.5 else None, c)

        steps["t"].append(t)
        steps["target_exists"].append(exists)
        steps["target_detectable"].append(detectable)
        for k, ax in enumerate("xyz"):
            steps[f"truth_{ax}"].append(truth[k])
            steps[f"est_{ax}"].append(est[k])
            steps[f"aim_{ax}"].append(aim[k] if t != 2 else np.nan)  # step 2: the fall-back
        steps["existence"].append(e)
        steps["ospa"].append(ospa)
        steps["objective"].append(float(rng.random()) if t != 2 else np.nan)
        steps["target_received_w"].append(float(to_target_w.sum()))
        steps["solve_s"].append(0.01 * t)

        for j in range(N):
            agents["t"].append(t)
            agents["agent"].append(j)
            for k, ax in enumerate("xyz"):
                agents[f"prev_{ax}"].append(u_prev[j, k])
                agents[ax].append(u[j, k])
                agents[f"point_{ax}"].append(point[j, k])
            agents["level_index"].append(int(level_index[j]))
            agents["power_w"].append(float(power_w[j]))
            agents["p_d"].append(float(p_d[j]))
            agents["detected"].append(bool(detected[j]))
            agents["measurements"].append(int(detected[j]) + int(rng.poisson(s.sensor.clutter_rate)))
            agents["existence"].append(float(own_e[j]))
            agents["interference_w"].append(float(interference_w[j]))
            agents["jammed"].append(bool(interference_w[j] >= ant.delta_w))
            agents["to_target_w"].append(float(to_target_w[j]))
        if exists:
            aim = truth.copy()

    return (
        {k: np.asarray(v) for k, v in steps.items()},
        {k: np.asarray(v) for k, v in agents.items()},
        s,
    )


def _ospa(x, x_hat, c: float) -> float:
    """OSPA(p, c) between sets of at most one point (docs/model.md, Metrics)."""
    if x is None and x_hat is None:
        return 0.0
    if x is None or x_hat is None:
        return c
    return float(min(np.linalg.norm(np.asarray(x) - np.asarray(x_hat)), c))


STEP_COLUMNS = [
    "t", "target_exists", "target_detectable", "truth_x", "truth_y", "truth_z", "existence",
    "est_x", "est_y", "est_z", "ospa", "aim_x", "aim_y", "aim_z", "objective",
    "target_received_w", "solve_s",
]
AGENT_COLUMNS = [
    "t", "agent", "prev_x", "prev_y", "prev_z", "x", "y", "z", "level_index", "power_w",
    "point_x", "point_y", "point_z", "p_d", "detected", "measurements", "existence",
    "interference_w", "jammed", "to_target_w",
]
