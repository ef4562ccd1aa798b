"""The swarm run's logs (long format, one row per step, per (step, target), per (step, reported
track), per (step, agent), per measurement; columns in :mod:`trackjam.simulation.swarm_schema`)
and its summary (per-target held share, multi-target OSPA with its cardinality part, incidents,
targets downed and when)."""

from __future__ import annotations

import numpy as np

import trackjam
from trackjam.metrics.ceiling import team_ceiling
from trackjam.metrics.multi import multi_track_quality
from trackjam.simulation.schema import conform
from trackjam.simulation.swarm_schema import SWARM_TABLES


def _xyz(prefix: str, v) -> dict:
    v = np.asarray(v, dtype=float).reshape(-1, 3)
    return {f"{prefix}_{k}": v[:, i] for i, k in enumerate("xyz")}


class SwarmLog:
    """Accumulates the rows of :class:`~trackjam.simulation.swarm.SwarmRecord` s."""

    def __init__(self, ids: list[str]) -> None:
        self.ids = ids
        self.rows: dict[str, dict[str, list]] = {name: {} for name in SWARM_TABLES}

    def _put(self, table: str, cols: dict) -> None:
        for k, v in cols.items():
            self.rows[table].setdefault(k, []).append(np.asarray(v))

    def add(self, r) -> None:
        self._put("steps", {k: [v] for k, v in r.step.items()})
        tg = dict(r.targets)
        self._put("targets", {"t": np.full(len(self.ids), r.t), "target": np.array(self.ids, dtype=str),
                              "exists": tg["exists"], "detectable": tg["detectable"], **_xyz("truth", tg["truth"]),
                              "received_w": tg["received_w"], "held": tg["held"],
                              "track": np.array(tg["track"], dtype=str), "downed": np.array(tg["downed"], dtype=bool)})
        tr = r.tracks
        m = len(tr["track"])
        self._put("tracks", {"t": np.full(m, r.t, dtype=np.int64), "track": np.array(tr["track"], dtype=str),
                             "existence": np.array(tr["existence"], dtype=float), **_xyz("est", tr["est"]),
                             "members": np.array(tr["members"], dtype=np.int64),
                             "target": np.array(tr["target"], dtype=str)})
        a = r.agents
        n = len(a["prev"])
        self._put("agents", {
            "t": np.full(n, r.t), "agent": np.arange(n), **_xyz("prev", a["prev"]),
            "x": a["pos"][:, 0], "y": a["pos"][:, 1], "z": a["pos"][:, 2], "level_index": a["level_index"],
            "power_w": a["power_w"], **_xyz("point", a["point"]), "serves": np.array(a["serves"], dtype=str),
            "detections": a["detections"], "measurements": a["measurements"], "tracks": a["tracks"],
            "interference_w": a["interference_w"], "jammed": a["jammed"], "to_targets_w": a["to_targets_w"],
            "mode": np.array(a["mode"], dtype=str), "heard": np.asarray(a["heard"], dtype=np.int64)})
        for j, (Z, source) in enumerate(r.scans):
            k = len(Z)
            names = np.array([self.ids[i] if i >= 0 else "" for i in source], dtype=str).reshape(k)
            self._put("measurements", {"t": np.full(k, r.t, dtype=np.int64), "agent": np.full(k, j, dtype=np.int64),
                                       "rho": Z[:, 0], "azimuth": Z[:, 1], "inclination": Z[:, 2], "target": names})

    def columns(self) -> dict[str, dict[str, np.ndarray]]:
        out = {}
        for table, schema in SWARM_TABLES.items():
            rows = self.rows[table]
            cols = {c.name: (np.concatenate(rows[c.name]) if rows.get(c.name) else np.zeros(0, dtype=c.dtype))
                    for c in schema}
            out[table] = conform(cols, schema, table)
        return out


def true_positions(tables: dict, ids: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The targets' true positions (T, K, 3), NaN while absent, and whether each is detectable (T, K)."""
    tg = tables["targets"]
    T, K = len(tables["steps"]["t"]), len(ids)
    return (np.stack([tg[f"truth_{a}"] for a in "xyz"], axis=1).reshape(T, K, 3),
            np.asarray(tg["detectable"], dtype=bool).reshape(T, K))


def truth_and_estimates(tables: dict, ids: list[str]) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """The logs as :mod:`trackjam.metrics.multi` takes them: the truth (T, K, 3), NaN where a
    target is not detectable, and per step the reported tracks as (labels, positions)."""
    tr = tables["tracks"]
    truth, detectable = true_positions(tables, ids)
    truth = truth.copy()
    truth[~detectable] = np.nan
    est = []
    for t in tables["steps"]["t"]:
        rows = tr["t"] == t
        est.append((tr["track"][rows], np.stack([tr[f"est_{a}"][rows] for a in "xyz"], axis=1)))
    return truth, est


def swarm_summary(tables: dict, ids: list[str], *, name: str, seed: int, solver: str, n_agents: int, gate: float,
                  downed_at: list[int | None], initial: np.ndarray, max_step: float, low, high) -> dict:
    """The swarm run's closing figures (README, "A run with several targets"), with the team's
    clairvoyant-chaser ceiling on the run's own truth (:func:`trackjam.metrics.ceiling.team_ceiling`:
    agents that start at ``initial`` and move ``max_step`` a step inside [low, high])."""
    steps, agents = tables["steps"], tables["agents"]
    incidents = agents["jammed"].reshape(-1, n_agents).sum(axis=0)
    truth, est = truth_and_estimates(tables, ids)
    ceiling = team_ceiling(*true_positions(tables, ids), initial, max_step, low, high)
    return {
        "name": name,
        "seed": seed,
        "version": trackjam.__version__,
        "steps": int(len(steps["t"])),
        "solver": solver,
        "n_targets": len(ids),
        "ospa_mean": float(np.mean(steps["ospa"])),
        "ospa_loc_mean": float(np.mean(steps["ospa_loc"])),
        "ospa_card_mean": float(np.mean(steps["ospa_card"])),
        "cardinality_error_mean": float(np.mean(np.abs(steps["tracks"] - steps["targets_detectable"]))),
        "jamming_incidents": [int(v) for v in incidents],
        "jamming_incidents_per_agent": float(incidents.mean()),
        "transmit_w_mean": float(np.mean(agents["power_w"])),
        "solve_s_mean": float(np.mean(steps["solve_s"])),
        "step_s_mean": float(np.mean(steps["step_s"])),
        "downed_at": list(downed_at),
        "targets_downed": sum(d is not None for d in downed_at),
        **multi_track_quality(truth, est, gate, ids),
        **ceiling.summary(),
    }
