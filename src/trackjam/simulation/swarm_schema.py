"""The swarm run's log columns (several targets, ours), declared once as in
:mod:`trackjam.simulation.schema`: one row per step, per (step, target), per (step, reported
track), per (step, agent) and per measurement. The README's tables under "A run with several
targets" are tested against these declarations."""

from __future__ import annotations

from trackjam.simulation.schema import AGENT_INTERFERENCE, AGENT_MOVE, SCAN_ROW, Column, _xyz

SWARM_STEPS: tuple[Column, ...] = (
    Column("t", "int64", "step", "step, 1..steps"),
    Column("targets_present", "int64", "", "truth targets present"),
    Column("targets_detectable", "int64", "", "truth targets present and not occluded"),
    Column("tracks", "int64", "", "tracks the team reports (fused existence > 0.5)"),
    Column("aims", "int64", "", "aims x_bar_k the team planned at: confirmed predicted tracks and search aims"),
    Column("ospa", "float64", "m", "multi-target OSPA(p, c) between the detectable targets and the reported tracks"),
    Column("ospa_loc", "float64", "m", "its localisation part"),
    Column("ospa_card", "float64", "m", "its cardinality part (ospa^p = loc^p + card^p)"),
    Column("mode", "str", "", "track (the solver planned at the aims), search (every aim a lost track's), hover (no aim: the fall-back levels), external (the actions were given: trackjam.env) or down (every agent broke down: comms.failures); under the comms faults, the lowest-index working agent's"),
    Column("objective", "float64", "", "the team objective (sum over the aims of Xi_k) of the plan; NaN under hover and external"),
    Column("optimal", "bool", "", "the plan is proven optimal"),
    Column("gap", "float64", "", "certified bound on optimum - objective; NaN without a certificate"),
    Column("solve_s", "float64", "s", "wall time of the control decision"),
    Column("step_s", "float64", "s", "wall time of the whole step"),
)

SWARM_TARGETS: tuple[Column, ...] = (
    Column("t", "int64", "step", "step"),
    Column("target", "str", "", "the target's id (`targets[k].id`, as text)"),
    Column("exists", "bool", "", "the target is present"),
    Column("detectable", "bool", "", "present and not occluded"),
    *_xyz("truth", "m", "true position; NaN when absent"),
    Column("received_w", "float64", "W", "power the target receives, summed over agents, Eq. (10)"),
    Column("held", "bool", "", "a reported track is assigned to it within metrics.gate (metrics/multi.py)"),
    Column("track", "str", "", "label of the reported track holding it; empty when none"),
    Column("downed", "bool", "", "its jamming fail-safe has started"),
)

SWARM_TRACKS: tuple[Column, ...] = (
    Column("t", "int64", "step", "step"),
    Column("track", "str", "", "the team's label of the track: aA:B.I, agent A's track born at step B as birth I"),
    Column("existence", "float64", "", "fused existence"),
    *_xyz("est", "m", "fused position estimate"),
    Column("members", "int64", "", "number of agents whose own track it fuses"),
    Column("target", "str", "", "id of the target it holds; empty: a false track"),
)

SWARM_AGENTS: tuple[Column, ...] = (
    *AGENT_MOVE,
    Column("serves", "str", "", "label of the track its cone serves; empty while hovering"),
    Column("detections", "int64", "", "target measurements in its scan"),
    Column("measurements", "int64", "", "measurements in its scan (targets and clutter)"),
    Column("tracks", "int64", "", "its own tracks with existence > 0.5, before fusion"),
    *AGENT_INTERFERENCE,
    Column("to_targets_w", "float64", "W", "power it delivers at the targets, summed over them, Eq. (10)"),
    Column("mode", "str", "", "track, search (it serves a lost track's search aim), hover or down (it broke down: comms.failures)"),
    Column("heard", "int64", "", "agents whose predicted tracks of this step it planned with, itself included (comms; 0 when down)"),
)

SWARM_MEASUREMENTS: tuple[Column, ...] = (
    *SCAN_ROW,
    Column("target", "str", "", "id of the target that made it; empty: clutter"),
)

SWARM_TABLES = {"steps": SWARM_STEPS, "targets": SWARM_TARGETS, "tracks": SWARM_TRACKS, "agents": SWARM_AGENTS,
                "measurements": SWARM_MEASUREMENTS}
