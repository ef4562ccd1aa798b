"""The run logs' columns, declared once: name, dtype, unit and meaning.

``steps.parquet`` has one row per step, ``agents.parquet`` one per (step, agent),
``measurements.parquet`` one per measurement. The logs are built to these declarations
(:mod:`trackjam.simulation.logs`), and the README's output tables are tested against them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Column:
    name: str
    dtype: str  # numpy dtype name: "int64", "float64", "bool" or "str"
    unit: str  # "" when dimensionless
    description: str


def _xyz(prefix: str, unit: str, description: str) -> tuple[Column, ...]:
    return tuple(Column(f"{prefix}_{k}", "float64", unit, f"{description} ({k})") for k in "xyz")


# column blocks every run's logs share, one target or several (simulation/swarm_schema.py)
AGENT_MOVE: tuple[Column, ...] = (
    Column("t", "int64", "step", "step"),
    Column("agent", "int64", "", "agent index, 0-based"),
    *_xyz("prev", "m", "position u_{t-1} before the step's move"),
    Column("x", "float64", "m", "position u_t after the move (x)"),
    Column("y", "float64", "m", "position u_t after the move (y)"),
    Column("z", "float64", "m", "position u_t after the move (z)"),
    Column("level_index", "int64", "", "index into antenna.power_levels_db (0 = off)"),
    Column("power_w", "float64", "W", "transmit power l_t"),
    *_xyz("point", "m", "the point the antenna axis aimed at while transmitting"),
)
AGENT_INTERFERENCE: tuple[Column, ...] = (
    Column("interference_w", "float64", "W", "power received from the other agents' cones, Eq. (13)'s left side"),
    Column("jammed", "bool", "", "interference_w >= delta"),
)
SCAN_ROW: tuple[Column, ...] = (
    Column("t", "int64", "step", "step"),
    Column("agent", "int64", "", "agent that received it"),
    Column("rho", "float64", "m", "range"),
    Column("azimuth", "float64", "rad", "azimuth in (-pi, pi]"),
    Column("inclination", "float64", "rad", "inclination"),
)


STEPS: tuple[Column, ...] = (
    Column("t", "int64", "step", "step, 1..steps"),
    Column("target_exists", "bool", "", "the truth target is present"),
    Column("target_detectable", "bool", "", "present and not occluded"),
    *_xyz("truth", "m", "true position; NaN when absent"),
    Column("existence", "float64", "", "fused existence probability e_hat of the team's report"),
    *_xyz("est", "m", "fused position estimate; NaN unless confirmed"),
    Column("ospa", "float64", "m", "OSPA(p, c) between the truth set and the estimate set"),
    Column("quality", "str", "", "track quality judged by the truth: held, false_track, missed, phantom, silent"),
    *_xyz("aim", "m", "planning aim x_bar of Eq. (12), moved ahead of the target under `control.lead` / "
          "`control.horizon`; NaN when no agent believes in the target; under `control.greedy_aim: own` the first "
          "working agent's own"),
    Column("mode", "str", "", "track, search, hover, external or down: the plan the report agent followed"),
    Column("objective", "float64", "", "Xi^N_n of the adopted plan at x_bar; NaN unless tracking"),
    Column("optimal", "bool", "", "the adopted plan is proven optimal"),
    Column("gap", "float64", "", "certified bound on optimum - objective; NaN without a certificate"),
    Column("closed_in", "bool", "", "the adopted plan closed in (`control.close_in`): moves of the plan without "
           "Eq. (13), levels chosen under it"),
    Column("target_received_w", "float64", "W", "power the target receives, summed over agents, Eq. (10)"),
    Column("solve_s", "float64", "s", "wall time of the control decision"),
    Column("step_s", "float64", "s", "wall time of the whole step"),
)

AGENTS: tuple[Column, ...] = (
    *AGENT_MOVE,
    Column("p_d", "float64", "", "detection probability at the true target, Eq. (9)"),
    Column("detected", "bool", "", "the scan held a target measurement"),
    Column("measurements", "int64", "", "measurements in the scan (target and clutter)"),
    Column("existence", "float64", "", "the agent's own existence e^j_t before fusion; NaN when broken down"),
    *AGENT_INTERFERENCE,
    Column("to_target_w", "float64", "W", "power this agent delivers at the target, Eq. (10)"),
    Column("mode", "str", "", "track, search, hover, external or down: the plan this agent followed"),
    Column("heard", "int64", "", "agents whose predictions of this step it planned with, itself included"),
)

MEASUREMENTS: tuple[Column, ...] = (
    *SCAN_ROW,
    Column("from_target", "bool", "", "a target measurement (False: clutter)"),
)

TABLES = {"steps": STEPS, "agents": AGENTS, "measurements": MEASUREMENTS}


def conform(columns: dict[str, np.ndarray], schema: tuple[Column, ...], table: str) -> dict[str, np.ndarray]:
    """The columns in schema order and dtype; a column missing or not declared is a bug."""
    names = [c.name for c in schema]
    if set(columns) != set(names):
        raise AssertionError(f"{table} log columns {sorted(set(columns) ^ set(names))} disagree with the schema")
    return {c.name: np.asarray(columns[c.name]).astype(c.dtype, copy=False) for c in schema}
