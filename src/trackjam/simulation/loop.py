"""The agents' loop: one step in the order MODEL.md fixes.

truth moves -> each agent predicts -> agents exchange predictions and form x_bar -> controls
are chosen (Eqs. 11-13) -> agents move and transmit -> each receives its scan and updates ->
the team fuses (covariance intersection) -> metrics.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

import trackjam
from trackjam.config import Scenario
from trackjam.control.solve import build_problem, fallback_levels, solve
from trackjam.estimation.fusion import fuse
from trackjam.metrics.ospa import ospa
from trackjam.radio.antenna import (
    AntennaModel,
    detection_probability,
    interference_matrix,
    received_power,
)
from trackjam.radio.measurement import sample_scan
from trackjam.simulation.agent import Agent, Exchange, planning_aim
from trackjam.simulation.logs import RunLog
from trackjam.world.moves import scenario_displacements
from trackjam.world.target import TruthTarget


@dataclass
class RunResult:
    """Everything one run produced: the resolved scenario, the logs as column arrays, and the
    summary figures (see :func:`summarise`)."""

    scenario: Scenario
    steps: dict[str, np.ndarray]
    agents: dict[str, np.ndarray]
    measurements: dict[str, np.ndarray]
    summary: dict


def default_threads(n_agents: int) -> int:
    """One thread per agent's GRASP search, up to the CPU count; 1 where the environment says
    one thread per process (experiment workers set TRACKJAM_THREADS=1)."""
    env = os.environ.get("TRACKJAM_THREADS")
    if env:
        return max(1, int(env))
    return max(1, min(n_agents, os.cpu_count() or 1))


def _seed_tree(scenario: Scenario) -> tuple[np.random.SeedSequence, list[list[np.random.SeedSequence]]]:
    """One root seed -> the truth's stream and three streams per agent (filter, sensor, plan)."""
    root = np.random.SeedSequence(scenario.seed)
    truth_seed, agents_seed = root.spawn(2)
    per_agent = [s.spawn(3) for s in agents_seed.spawn(scenario.n_agents)]
    return truth_seed, per_agent


def simulate(scenario: Scenario, progress: Callable[[int, int], None] | None = None) -> RunResult:
    """Run one scenario end to end and return its logs and summary."""
    s = scenario
    ant = AntennaModel.from_scenario(s)
    D = scenario_displacements(s)
    low, high = np.asarray(s.area.low, float), np.asarray(s.area.high, float)
    truth_seed, agent_seeds = _seed_tree(s)
    truth = TruthTarget(s, np.random.default_rng(truth_seed))

    initial_aim = s.agents.initial_aim
    if initial_aim is None:
        initial_aim = truth.first_state[:3]
    agents = [
        Agent.create(j, s, u, initial_aim, agent_seeds[j]) for j, u in enumerate(s.agents.initial)
    ]
    exchange = Exchange()
    log = RunLog(n_agents=len(agents))
    delta = ant.delta_w
    threads = s.control.threads or default_threads(len(agents))
    q_var = s.filter_accel_var

    for t in range(1, s.steps + 1):
        t0 = time.perf_counter()
        # 1. the truth moves
        truth.step(t)
        x_true = truth.position

        # 2-3. predictions are exchanged; every agent forms the same x_bar from them
        predictions = exchange.all_to_all([a.predict() for a in agents])
        for a in agents:
            a.receive(predictions)
        # each agent forms x_bar from its own view; the views are equal, so are the aims
        x_bar = planning_aim(agents[0].view)

        # 4. controls
        positions = np.array([a.position for a in agents])
        ts = time.perf_counter()
        if x_bar is not None or s.control.fallback == "search":
            # tracking plans at x_bar; a searching team plans around the aim it last had
            plan_aim = x_bar if x_bar is not None else search_aim(predictions, agents, low, high, q_var)
            problem = build_problem(
                positions, plan_aim, D, ant, low, high, s.control.at_least, s.control.constraints
            )
            sol = solve(
                problem,
                s.control.solver,
                [a.plan_rng for a in agents],
                samples=s.control.samples,
                iterations=s.control.iterations,
                neighbours=s.control.neighbours,
                threads=threads,
            )
            moves, levels = sol.move, sol.level
            objective = sol.objective if x_bar is not None else np.nan
            for a in agents:
                a.aim = plan_aim.copy()
            mode = "track" if x_bar is not None else "search"
        else:
            aims = np.array([a.aim for a in agents])
            moves = np.zeros(len(agents), dtype=np.int64)
            levels = fallback_levels(positions, aims, ant, s.control.constraints)
            objective = np.nan
            mode = "hover"
        solve_s = time.perf_counter() - ts

        # 5. move and transmit
        prev = positions
        for a, k in zip(agents, moves):
            a.position = a.position + D[k]
        positions = np.array([a.position for a in agents])
        if s.antenna.pointing == "truth" and x_true is not None:
            points = np.repeat(x_true[None, :], len(agents), axis=0)
        else:
            points = np.array([a.aim for a in agents])
        level_w = ant.levels_w[np.asarray(levels, dtype=np.int64)]
        R = interference_matrix(positions, points, level_w, ant)
        interference = R.sum(axis=1)
        # occlusion hides the target from detection (MODEL.md); the jamming power still reaches it
        p_d = np.zeros(len(agents))
        to_target = np.zeros(len(agents))
        if truth.exists:
            to_target = received_power(x_true, positions, points, level_w, ant)
            if truth.detectable:
                p_d = detection_probability(x_true, positions, points, level_w, ant)
        truth.apply_jamming(t, float(to_target.sum()))

        # 6. scans and filter updates
        scans = []
        posteriors = []
        for j, a in enumerate(agents):
            Z, from_target = sample_scan(
                a.sensor_rng,
                x_true if truth.detectable else None,
                a.position,
                float(p_d[j]),
                s.sensor.noise_std,
                s.sensor.clutter_rate,
                ant.max_range,
            )
            scans.append((Z, from_target))
            posteriors.append(a.update(Z, points[j], float(level_w[j])))
        own_existence = np.array([m.estimate.existence for m in posteriors])

        # 7. fusion, sent back to every agent
        posteriors = exchange.all_to_all(posteriors)
        for a in agents:
            a.receive(posteriors)
        fused = fuse(
            [m.estimate for m in posteriors],
            predicted=[m.estimate.existence for m in predictions],
            rule=s.fusion.existence,
        )
        for a in agents:
            a.remember(fused.existence, fused.mean, fused.cov)
            if not s.fusion.feedback:
                continue
            if fused.mean is None and s.control.fallback == "search" and a.last_track is not None:
                # a searching team coasts its lost track: the spatial density is the last fused
                # estimate predicted by Eq. (1), the existence the fused one (ours)
                mean, cov = a.coasted_track(q_var)
                a.filter.reset_to(fused.existence, mean, cov)
            else:
                a.filter.reset_to(fused.existence, fused.mean, fused.cov)

        # 8. metrics
        est = fused.mean[:3] if (fused.existence > 0.5 and fused.mean is not None) else None
        truth_set = x_true if truth.detectable else None
        err = ospa(truth_set, est, c=s.metrics.ospa_cutoff, p=s.metrics.ospa_order)
        step_s = time.perf_counter() - t0

        log.add_step(
            t=t,
            target_exists=truth.exists,
            target_detectable=truth.detectable,
            truth=x_true,
            existence=fused.existence,
            estimate=est,
            ospa=err,
            aim=x_bar,
            mode=mode,
            objective=objective,
            target_received_w=float(to_target.sum()),
            solve_s=solve_s,
            step_s=step_s,
        )
        log.add_agents(
            t=t,
            prev=prev,
            pos=positions,
            level_index=np.asarray(levels),
            power_w=level_w,
            point=points,
            p_d=p_d,
            detected=np.array([bool(f.any()) for _, f in scans]),
            n_measurements=np.array([len(Z) for Z, _ in scans]),
            existence=own_existence,
            interference_w=interference,
            jammed=interference >= delta,
            to_target_w=to_target,
        )
        log.add_measurements(t, scans)
        if progress is not None:
            progress(t, s.steps)

    steps, agents_log, meas = log.columns()
    summary = summarise(steps, agents_log, s, downed_at=truth.downed_at)
    return RunResult(s, steps, agents_log, meas, summary)


def search_aim(predictions, agents, low, high, accel_var: float, spread: float = 10.0) -> np.ndarray:
    """Where a team that tracks nothing looks (ours, `control.fallback: search`): its last
    confirmed track coasted by Eq. (1); if it never tracked, the mean predicted position of the
    agents whose predicted density is compact (position standard deviation under ``spread``
    metres); else the current aim."""
    coasting = [a.coasted_track(accel_var) for a in agents]
    coasting = [c[0][:3] for c in coasting if c is not None]
    if coasting:
        return np.clip(np.mean(coasting, axis=0), low, high)
    compact = [
        m.estimate.mean[:3]
        for m in predictions
        if np.sqrt(np.trace(m.estimate.cov[:3, :3]) / 3) < spread
    ]
    if compact:
        return np.clip(np.mean(compact, axis=0), low, high)
    return np.mean([a.aim for a in agents], axis=0)


def summarise(steps: dict, agents: dict, scenario: Scenario, downed_at: int | None = None) -> dict:
    """The run's table: the paper's Fig. 4/5 metrics for one trial."""
    n = scenario.n_agents
    jammed = agents["jammed"].reshape(-1, n)
    incidents = jammed.sum(axis=0)
    return {
        "name": scenario.name,
        "seed": scenario.seed,
        "version": trackjam.__version__,
        "steps": int(scenario.steps),
        "solver": scenario.control.solver,
        "ospa_mean": float(np.mean(steps["ospa"])),
        "jamming_incidents": [int(v) for v in incidents],
        "jamming_incidents_per_agent": float(incidents.mean()),
        "target_received_w_mean": float(np.mean(steps["target_received_w"])),
        "agent_received_w_mean": float(np.mean(agents["interference_w"])),
        "transmit_w_mean": float(np.mean(agents["power_w"])),
        "solve_s_mean": float(np.mean(steps["solve_s"])),
        "step_s_mean": float(np.mean(steps["step_s"])),
        "tracked_steps": int(np.sum(steps["existence"] > 0.5)),
        "downed_at": downed_at,
    }
