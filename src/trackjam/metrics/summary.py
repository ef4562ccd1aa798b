"""A run's closing figures: the paper's Fig. 4/5 metrics for one trial, the track quality judged
by the truth and the clairvoyant-chaser ceiling on the run's own truth (both ours)."""

from __future__ import annotations

import numpy as np

import trackjam
from trackjam.estimation.fusion import CONFIRM
from trackjam.metrics.ceiling import clairvoyant_ceiling
from trackjam.metrics.track_quality import track_quality


def summarise(steps: dict, agents: dict, *, name: str, seed: int, n_agents: int, solver: str,
              gate: float, initial: np.ndarray, max_step: float, low, high,
              downed_at: int | None = None) -> dict:
    """The run's table from its step and agent logs (column arrays). ``gate`` is metrics.gate
    [m]; ``initial`` (N, 3) the agents' start, ``max_step`` max(Delta_R) [m] and ``low``,
    ``high`` the area's corners, for the ceiling."""
    jammed = agents["jammed"].reshape(-1, n_agents)
    incidents = jammed.sum(axis=0)
    truth = np.stack([np.asarray(steps[f"truth_{a}"], dtype=float) for a in "xyz"], axis=1)
    ceiling = clairvoyant_ceiling(truth, steps["target_detectable"], initial, max_step, low, high)
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
        # the steps the team reported a track (track quality's "confirmed": fused existence > 0.5
        # and an estimate, which the report rule of filter.visibility and fusion.report_spread
        # can withhold), on the target or not: held_steps says which were on it
        "confirmed_steps": int(np.sum((np.asarray(steps["existence"], dtype=float) > CONFIRM)
                                      & np.isfinite(np.asarray(steps["est_x"], dtype=float)))),
        "closed_in_steps": int(np.sum(steps["closed_in"])) if "closed_in" in steps else 0,  # control.close_in
        "downed_at": downed_at,
        **track_quality(steps, gate),
        **ceiling.summary(),
    }
