"""A run's closing figures: the paper's Fig. 4/5 metrics for one trial."""

from __future__ import annotations

import numpy as np

import trackjam
from trackjam.estimation.fusion import CONFIRM


def summarise(steps: dict, agents: dict, *, name: str, seed: int, n_agents: int, solver: str,
              downed_at: int | None = None) -> dict:
    """The run's table from its step and agent logs (column arrays)."""
    jammed = agents["jammed"].reshape(-1, n_agents)
    incidents = jammed.sum(axis=0)
    return {
        "name": name,
        "seed": seed,
        "version": trackjam.__version__,
        "steps": int(len(steps["t"])),
        "solver": solver,
        "ospa_mean": float(np.mean(steps["ospa"])),
        "jamming_incidents": [int(v) for v in incidents],
        "jamming_incidents_per_agent": float(incidents.mean()),
        "target_received_w_mean": float(np.mean(steps["target_received_w"])),
        "agent_received_w_mean": float(np.mean(agents["interference_w"])),
        "transmit_w_mean": float(np.mean(agents["power_w"])),
        "solve_s_mean": float(np.mean(steps["solve_s"])),
        "step_s_mean": float(np.mean(steps["step_s"])),
        "tracked_steps": int(np.sum(steps["existence"] > CONFIRM)),
        "downed_at": downed_at,
    }
