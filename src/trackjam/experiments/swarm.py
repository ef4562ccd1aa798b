"""The swarm experiment (ours, issue 12): K targets x N agents on the swarm engine, with the
targets' jamming response on: its grid, its trial draw, its configurations and paired
comparisons, and the record a trial reduces to.

Trial k of cell (K, N) (the README's "The swarm experiment" and docs/model.md fix the choices):

- target i (i < K) is drawn as the paper's Section VI draws its one target: position uniform in
  the area, velocity uniform in +-v_b per axis (v_b = ``filter.birth_speed``), present from step
  1, never occluded; it lands (``targets[i].response``: -40 dB for 3 steps, 2 m/step) when jammed;
- agent j (j < N) is uniform in the 20 m ball around target j mod K, inside the area (the
  paper's ball, one per target in turn); it first points at that target (the swarm engine's
  default) and every filter is cued on every target's first position (``filter.cue``);
- every draw has its own stream: target i of trial k from SeedSequence(seed, (2, k, 0, i)),
  agent j of cell (K, N) from (2, k, 1, K, j), so the cells of trial k with the same K have the
  same targets and share agents (N = 4 is N = 3 plus one agent), and the cells with more
  targets add targets to those of fewer;
- the simulation seed of trial k is the same in every cell (SeedSequence(seed, (1, 0, k)), as in
  ``holding``): each target's random walk and each agent's streams are the same in every cell
  where they exist. Comparisons across N at one K are paired.

A cell with ``one_target`` runs the same K = 1 trials on the one-target engine (the scenario
gives ``target:`` instead of a list of one), the check that the swarm engine with one target
agrees with it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from trackjam.errors import ConfigError, shortened
from trackjam.experiments.experiment import SWARM, Configuration, Experiment, Panel
from trackjam.experiments.progress import SWARM_SHOWN
from trackjam.experiments.summary import Metric, Pair
from trackjam.experiments.trials import BALL_RADIUS_M, uniform_in_ball
from trackjam.estimation.fusion import CONFIRM
from trackjam.metrics.multi import HELD, UNDETECTABLE, multi_track_quality, ospa_series, target_classes

DEFAULT_GRID: tuple[tuple[int, ...], tuple[int, ...]] = ((1, 2, 3, 4), (3, 4, 5, 6))  # (K values, N values)
MAX_GRID_TARGETS = 8  # beyond it a cell no longer fits the machine (and the swarm engine plans at 4 aims)
MAX_GRID_AGENTS = 12
GRID_SHOWN = 40  # characters of a --grid value a message shows
NODE_LIMIT = 2_000_000  # exact's budget per search in the sweep [search nodes]
RESPONSE = {"action": "land"}  # the rest is the configuration's default: -40 dB for 3 steps, 2 m/step
_SWARM, _TARGET, _AGENT = 2, 0, 1  # spawn-key entries of the swarm draw (0 and 1 are trials.py's)

# (column stem, key of a trial record, meaning [unit]); shares are of detectable (target, step) pairs
SWARM_METRICS: tuple[Metric, ...] = (
    ("held", "held_share", "held share per target: mean over the targets of held / detectable steps [0-1]"),
    ("held50", "held50_share", "share of the targets held on >= 50 % of their detectable steps [0-1]"),
    ("held_airborne", "held_airborne_share", "held share per target over its detectable steps up to the one it "
     "was downed at (all, if never downed) [0-1]"),
    ("ceiling", "ceiling_share", "the clairvoyant-chaser ceiling per target: mean over the targets of the share of their "
     "detectable steps with a chaser within 8 m, on the trial's own truth [0-1]"),
    ("ceiling50", "ceiling50_share", "share of the targets whose ceiling is >= 50 % [0-1]"),
    ("missed", "missed_share", "missed target-steps / detectable target-steps [0-1]"),
    ("false_tracks", "false_tracks_per_step", "confirmed tracks assigned to no target, per step"),
    ("ospa", "ospa_mean", "multi-target OSPA (p=2, c=10 m), mean over steps [m]"),
    ("ospa_card", "ospa_card_mean", "its cardinality part, mean over steps [m]"),
    ("downed", "downed_share", "share of the targets downed (their jamming fail-safe started) [0-1]"),
    ("time_to_down", "downed_step_mean", "step the fail-safe started, mean over the downed targets [steps]"),
    ("incidents", "jamming_incidents_per_agent", "jamming incidents per trial per agent [steps]"),
    ("transmit_w", "transmit_w_mean", "transmit power per agent and step [W]"),
)


def _whole(digits: str) -> int | float:
    """The number ``digits`` writes; past 18 digits (leading zeros aside) infinity, as out of
    range as it is: Python refuses to convert more than 4300."""
    digits = digits.lstrip("0") or "0"
    return int(digits) if len(digits) <= 18 else math.inf


def _values(text: str, what: str, top: int) -> tuple[int, ...]:
    out: list[int] = []
    for part in text.split(","):
        m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", part, re.ASCII)
        if m is None:
            raise ConfigError(f"--grid: {what} {shortened(text, GRID_SHOWN)!r} is not a list of whole numbers or ranges (e.g. 1-4 or 3,5)")
        a, b = _whole(m[1]), _whole(m[2] or m[1])
        if not 1 <= a <= b <= top:
            raise ConfigError(f"--grid: {what} {shortened(part.strip(), GRID_SHOWN)!r} must lie within 1..{top}, low to high")
        out += range(a, b + 1)
    if len(set(out)) != len(out):
        raise ConfigError(f"--grid: {what} {shortened(text, GRID_SHOWN)!r} lists a value twice")
    return tuple(sorted(out))


def parse_grid(text: str | None) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """``KxN`` (targets x agents), each side a comma list of numbers or ranges: ``1-4x3-6`` is the
    default grid, ``3x5`` one cell; None: the default."""
    if text is None:
        return DEFAULT_GRID
    targets, sep, agents = text.strip().partition("x")
    if not sep or not targets or not agents:
        raise ConfigError(f"--grid {shortened(text, GRID_SHOWN)!r}: expected TARGETSxAGENTS, e.g. 1-4x3-6 or 2,3x5")
    return _values(targets, "targets", MAX_GRID_TARGETS), _values(agents, "agents", MAX_GRID_AGENTS)


def grid_text(grid: tuple[tuple[int, ...], tuple[int, ...]]) -> str:
    return ",".join(map(str, grid[0])) + "x" + ",".join(map(str, grid[1]))


@dataclass(frozen=True)
class SwarmDraw:
    """The initial condition of one trial in one cell."""

    index: int
    x0: np.ndarray  # (K, 6) target states at step 1 [m, m/s]
    u0: np.ndarray  # (N, 3) agent positions [m]


def _rng(seed: int, *key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_SWARM, *key)))


def draw_swarm(seed: int, k: int, n_targets: int, n_agents: int, low, high, birth_speed: float,
               radius: float = BALL_RADIUS_M) -> SwarmDraw:
    """Trial k of cell (``n_targets``, ``n_agents``) (the module docstring)."""
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    x0 = np.empty((n_targets, 6))
    for i in range(n_targets):
        rng = _rng(seed, k, _TARGET, i)
        x0[i, :3] = rng.uniform(low, high)
        x0[i, 3:] = rng.uniform(-birth_speed, birth_speed, size=3)
    u0 = np.empty((n_agents, 3))
    for j in range(n_agents):
        rng = _rng(seed, k, _AGENT, n_targets, j)
        while True:  # rejection: uniform in the part of the ball inside the area
            u = uniform_in_ball(rng, x0[j % n_targets, :3], radius)
            if np.all(u >= low) and np.all(u <= high):
                break
        u0[j] = u
    return SwarmDraw(k, x0, u0)


def swarm_fields(draw: SwarmDraw, one_target: bool = False) -> dict[str, Any]:
    """Top-level scenario keys that place ``draw``: its targets (a list, ids 0..K-1, or the one
    ``target`` for the one-target engine) and agents."""
    targets = [{"id": i, "initial": [float(v) for v in x], "appears": 1, "disappears": None, "occlusions": [],
                "stochastic": None, "response": dict(RESPONSE)} for i, x in enumerate(draw.x0)]
    placed: dict[str, Any] = {"agents.initial": [[float(v) for v in u] for u in draw.u0], "agents.initial_aim": None}
    if one_target:
        if len(targets) != 1:
            raise ValueError("the one-target engine runs cells with one target")
        target = {k: v for k, v in targets[0].items() if k != "id"}
        return {**placed, "targets": None, "target": target}
    return {**placed, "target": None, "targets": targets}


# ---------------------------------------------------------------------------------------------
# the experiment

# ours, several targets: each metric against K, one line per N (experiments/swarm_figure.py)
SWARM_PANELS = (
    Panel("(a) held share per target", "share of detectable steps",
          (("held", None), ("ceiling", "ceiling: clairvoyant chasers within 8 m"))),
    Panel("(b) held share while airborne (until downed)", "share of detectable steps", (("held_airborne", None),)),
    Panel("(c) targets held on >= 50 % of their steps", "share of targets",
          (("held50", None), ("ceiling50", "the chasers' ceiling >= 50 %"))),
    Panel("(d) multi-target tracking error", "OSPA (p=2, c=10) [m]", (("ospa", None),)),
    Panel("(e) targets downed", "share of targets", (("downed", None),)),
    Panel("(f) time to down a target", "step of the fail-safe", (("time_to_down", None),)),
)


def swarm_experiment(grid: str | None = None) -> Experiment:
    """``swarm`` over the grid ``grid`` (TARGETSxAGENTS, default 1-4x3-6): a configuration per
    cell (K, N), K-major, then the K = 1 cells again on the one-target engine."""
    targets, agents = parse_grid(grid)
    cells = [Configuration(0, f"K={k}, N={n}", cell=(k, n)) for k in targets for n in agents]
    cells += [Configuration(0, f"K=1, N={n}, one-target engine", cell=(1, n), one_target=True)
              for n in agents if 1 in targets]
    configurations = tuple(Configuration(i, c.label, cell=c.cell, one_target=c.one_target)
                           for i, c in enumerate(cells, start=1))
    return Experiment(
        "swarm",
        "ours: K targets x N agents on the swarm engine, jamming response on",
        configurations,
        "swarm.png",
        panels=SWARM_PANELS,
        metrics=SWARM_METRICS,
        trials=SWARM,
        preset="swarm-3",
        # the cue at rest, as the README's results were measured (the preset cues velocities since);
        # the filters expect the fail-safe the targets have (filter.response: estimation/failsafe.py)
        # exact's budget in search nodes, not wall time, so that a sweep repeats exactly under any
        # load (2 million nodes: about the 1 s budget on this machine's hardest K = 3..4 steps)
        base_settings={"filter.cue.velocity": "zero", "filter.response": dict(RESPONSE),
                       "control.node_limit": NODE_LIMIT, "control.time_limit_s": 3600.0},
        trial=swarm_trial,
        figure_style="lines",
        shown=SWARM_SHOWN,
        grid=grid_text((targets, agents)),
        pairs=swarm_pairs(configurations),
    )


def swarm_pairs(configurations: tuple[Configuration, ...]) -> tuple[Pair, ...]:
    """The swarm's paired comparisons: at each K, each N against the next and the smallest team
    against the largest; at each N, each K against the next and the fewest targets against the
    most; each K = 1 cell on the swarm engine against the one-target engine."""
    swarm = {c.cell: c.index for c in configurations if not c.one_target}
    reference = {c.cell: c.index for c in configurations if c.one_target}
    targets, agents = sorted({k for k, _ in swarm}), sorted({n for _, n in swarm})

    def chain(values: list[int]) -> list[tuple[int, int]]:
        steps = list(zip(values, values[1:]))
        return steps + ([(values[0], values[-1])] if len(values) > 2 else [])

    pairs = [(swarm[(k, a)], swarm[(k, b)], f"K={k}: N={a} -> N={b}") for k in targets for a, b in chain(agents)]
    pairs += [(swarm[(a, n)], swarm[(b, n)], f"N={n}: K={a} -> K={b}") for n in agents for a, b in chain(targets)]
    pairs += [(reference[cell], swarm[cell], f"K=1, N={cell[1]}: one-target engine -> swarm engine")
              for cell in reference]
    return tuple(pairs)


# ---------------------------------------------------------------------------------------------
# the trial: a run reduced to its record


def _nan(v: float | None) -> float:
    return math.nan if v is None else float(v)


def airborne_shares(classes: np.ndarray, downed_at: list[int | None]) -> list[float]:
    """Per target, its held share over its detectable steps 1..downed_at (every step if never
    downed): how well the team held it while it was still a threat (NaN: never detectable then)."""
    out = []
    for k, d in enumerate(downed_at):
        c = classes[: len(classes) if d is None else d, k]
        n = int((c != UNDETECTABLE).sum())
        out.append(float((c == HELD).sum() / n) if n else math.nan)
    return out


def swarm_record(quality: dict, classes: np.ndarray, ospa: np.ndarray, downed_at: list[int | None],
                 incidents: list[int], transmit_w: float, step_s: float, solve_s: float,
                 steps: dict[str, np.ndarray], ceiling: list[float | None]) -> dict[str, Any]:
    """A trial's record from its track quality (:func:`trackjam.metrics.multi.multi_track_quality`)
    and per-step classes (T, K) (:func:`trackjam.metrics.multi.target_classes`), its (T, 3) OSPA
    series (total, localisation, cardinality), each target's step of downing, each agent's
    incidents and each target's clairvoyant-chaser ceiling (:mod:`trackjam.metrics.ceiling`)."""
    shares = [s for s in quality["held_share"] if s is not None]
    reach = [c for c in ceiling if c is not None]
    airborne = [s for s in airborne_shares(classes, downed_at) if not math.isnan(s)]
    n_det = quality["detectable_steps_total"]
    downed = [d for d in downed_at if d is not None]
    K, T = len(downed_at), len(ospa)
    return {
        "held_share": float(np.mean(shares)) if shares else math.nan,
        "held50_share": float(np.mean([s >= 0.5 for s in shares])) if shares else math.nan,
        "ceiling_share": float(np.mean(reach)) if reach else math.nan,
        "ceiling50_share": float(np.mean([c >= 0.5 for c in reach])) if reach else math.nan,
        "held_airborne_share": float(np.mean(airborne)) if airborne else math.nan,
        "missed_share": (n_det - quality["held_steps_total"]) / n_det if n_det else math.nan,
        "false_tracks_per_step": quality["false_tracks"] / T,
        "ospa_mean": float(ospa[:, 0].mean()),
        "ospa_card_mean": float(ospa[:, 2].mean()),
        "downed_share": len(downed) / K,
        "downed_step_mean": float(np.mean(downed)) if downed else math.nan,
        "jamming_incidents_per_agent": float(np.mean(incidents)),
        "jamming_incidents": [int(v) for v in incidents],
        "transmit_w_mean": float(transmit_w),
        "label_switches_per_target": float(np.mean(quality["label_switches"])),
        "step_s_mean": float(step_s),
        "solve_s_mean": float(solve_s),
        "targets": {
            "held_share": [_nan(s) for s in quality["held_share"]],
            "ceiling_share": [_nan(c) for c in ceiling],
            "detectable_steps": [float(v) for v in quality["detectable_steps"]],
            "downed_at": [_nan(d) for d in downed_at],
        },
        "steps": {**steps, "ospa": ospa[:, 0], "ospa_card": ospa[:, 2], "held_targets": (classes == HELD).sum(axis=1)},
    }


def _swarm_run(scenario) -> dict[str, Any]:
    from trackjam.simulation.swarm import SwarmSimulation
    from trackjam.simulation.swarm_logs import truth_and_estimates

    sim = SwarmSimulation(scenario)
    while not sim.done:
        sim.step()
    r = sim.result()
    s, st = r.summary, r.tables["steps"]
    classes = target_classes(*truth_and_estimates(r.tables, s["ids"]), s["gate_m"])[0]
    ospa = np.stack([st["ospa"], st["ospa_loc"], st["ospa_card"]], axis=1)
    return swarm_record(s, classes, ospa, s["downed_at"], s["jamming_incidents"], s["transmit_w_mean"],
                        s["step_s_mean"], s["solve_s_mean"], {"t": st["t"], "tracks": st["tracks"]}, s["ceiling_share"])


def one_target_estimates(steps: dict[str, np.ndarray]) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """A one-target run's steps log as :mod:`trackjam.metrics.multi` takes a swarm run's: the
    truth (T, 1, 3), NaN where not detectable, and per step the confirmed report (existence > 0.5
    with a position) as a track labelled 0."""
    truth = np.stack([np.asarray(steps[f"truth_{a}"], dtype=float) for a in "xyz"], axis=1)
    truth[~np.asarray(steps["target_detectable"], dtype=bool)] = np.nan
    est = np.stack([np.asarray(steps[f"est_{a}"], dtype=float) for a in "xyz"], axis=1)
    sure = (np.asarray(steps["existence"], dtype=float) > CONFIRM) & np.isfinite(est).all(axis=1)
    reports = [(np.array(["0"]), est[t:t + 1]) if sure[t] else (np.array([], dtype=str), np.zeros((0, 3)))
               for t in range(len(est))]
    return truth[:, None, :], reports


def _one_target_run(scenario) -> dict[str, Any]:
    from trackjam.simulation.engine import Simulation

    sim = Simulation(scenario)
    while not sim.done:
        sim.step()
    r = sim.result()
    s, m = r.summary, scenario.metrics
    truth, reports = one_target_estimates(r.steps)
    quality = multi_track_quality(truth, reports, m.gate, [0])
    classes = target_classes(truth, reports, m.gate)[0]
    ospa = ospa_series(truth, reports, c=m.ospa_cutoff, p=m.ospa_order)
    return swarm_record(quality, classes, ospa, [s["downed_at"]], s["jamming_incidents"], s["transmit_w_mean"],
                        s["step_s_mean"], s["solve_s_mean"],
                        {"t": r.steps["t"], "tracks": np.array([len(lab) for lab, _ in reports])},
                        [s["ceiling_share"]])


def swarm_trial(scenario) -> dict[str, Any]:
    """A trial of the swarm experiment: the swarm engine for a list of targets (K = 1 too), the
    one-target engine for a scenario that gives the one ``target``."""
    return _one_target_run(scenario) if scenario.targets is None else _swarm_run(scenario)
