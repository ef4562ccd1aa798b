"""Column logs of a run: steps, agents and measurements, kept as arrays and written as Parquet.

Every column is declared once, in :mod:`trackjam.simulation.schema`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trackjam.metrics.track_quality import CLASSES, step_classes
from trackjam.simulation.schema import AGENTS, MEASUREMENTS, STEPS, conform

NAN3 = (np.nan, np.nan, np.nan)


def _xyz(prefix: str, v) -> dict:
    v = NAN3 if v is None else v
    return {f"{prefix}_x": float(v[0]), f"{prefix}_y": float(v[1]), f"{prefix}_z": float(v[2])}


class RunLog:
    """Accumulates one row per step, per (step, agent) and per measurement."""

    def __init__(self, n_agents: int, gate: float = 5.0) -> None:
        self.n = n_agents
        self.gate = gate  # metrics.gate [m], for the steps' `quality` column
        self.steps: list[dict] = []
        self.agents: dict[str, list] = {}
        self.meas: dict[str, list] = {c.name: [] for c in MEASUREMENTS}

    def add_step(self, *, t, target_exists, target_detectable, truth, existence, estimate, ospa, aim,
                 mode, objective, optimal, gap, closed_in, target_received_w, solve_s, step_s) -> None:
        row = {"t": t, "target_exists": bool(target_exists), "target_detectable": bool(target_detectable)}
        row |= _xyz("truth", truth)
        row["existence"] = float(existence)
        row |= _xyz("est", estimate)
        row["ospa"] = float(ospa)
        row |= _xyz("aim", aim)
        row["mode"] = mode
        row |= {"objective": float(objective), "optimal": bool(optimal), "gap": float(gap),
                "closed_in": bool(closed_in), "target_received_w": float(target_received_w),
                "solve_s": float(solve_s), "step_s": float(step_s)}
        self.steps.append(row)

    def add_agents(self, *, t, prev, pos, level_index, power_w, point, p_d, detected, n_measurements,
                   existence, interference_w, jammed, to_target_w, mode, heard) -> None:
        cols = {
            "t": np.full(self.n, t, dtype=np.int64),
            "agent": np.arange(self.n, dtype=np.int64),
            "prev_x": prev[:, 0], "prev_y": prev[:, 1], "prev_z": prev[:, 2],
            "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2],
            "level_index": np.asarray(level_index, dtype=np.int64),
            "power_w": np.asarray(power_w, dtype=float),
            "point_x": point[:, 0], "point_y": point[:, 1], "point_z": point[:, 2],
            "p_d": np.asarray(p_d, dtype=float),
            "detected": np.asarray(detected, dtype=bool),
            "measurements": np.asarray(n_measurements, dtype=np.int64),
            "existence": np.asarray(existence, dtype=float),
            "interference_w": np.asarray(interference_w, dtype=float),
            "jammed": np.asarray(jammed, dtype=bool),
            "to_target_w": np.asarray(to_target_w, dtype=float),
            "mode": np.asarray(mode, dtype=str),
            "heard": np.asarray(heard, dtype=np.int64),
        }
        for k, v in cols.items():
            self.agents.setdefault(k, []).append(np.array(v, copy=True))

    def add(self, record) -> None:
        """The rows of one :class:`~trackjam.simulation.engine.StepRecord`."""
        self.add_step(**record.step)
        self.add_agents(**record.agents)
        self.add_measurements(record.t, record.scans)

    def add_measurements(self, t: int, scans: list[tuple[np.ndarray, np.ndarray]]) -> None:
        for j, (Z, from_target) in enumerate(scans):
            m = len(Z)
            self.meas["t"].append(np.full(m, t, dtype=np.int64))
            self.meas["agent"].append(np.full(m, j, dtype=np.int64))
            self.meas["rho"].append(Z[:, 0])
            self.meas["azimuth"].append(Z[:, 1])
            self.meas["inclination"].append(Z[:, 2])
            self.meas["from_target"].append(np.asarray(from_target, dtype=bool))

    def columns(self) -> tuple[dict, dict, dict]:
        steps = {k: np.array([r[k] for r in self.steps]) for k in self.steps[0]} if self.steps else {}
        if steps:
            steps = _with_quality(steps, self.gate)
        agents = {k: np.concatenate(v) for k, v in self.agents.items()}
        meas = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in self.meas.items()}
        if not steps:
            return steps, agents, conform(meas, MEASUREMENTS, "measurements")
        return (conform(steps, STEPS, "steps"), conform(agents, AGENTS, "agents"),
                conform(meas, MEASUREMENTS, "measurements"))


def _with_quality(steps: dict, gate: float) -> dict:
    """The steps' columns with ``quality``: the track-quality class name of each step, judged by
    the truth within ``gate`` m."""
    return steps | {"quality": np.asarray(CLASSES)[step_classes(steps, gate)]}


def write_parquet(columns: dict[str, np.ndarray], path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    with open(path, "wb") as fh:  # a file object: pyarrow's own path handling refuses a name that is not UTF-8
        pq.write_table(pa.table({k: np.asarray(v) for k, v in columns.items()}), fh)
