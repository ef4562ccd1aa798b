"""Benchmarks of the step's cooperative control on random instances drawn like the paper's
trials (Section VI): target uniform in the area, N agents uniform in a 20 m ball around it
(clipped to the area), aim x_bar = the target's position, the paper's antenna with an opening
angle drawn from {60, 80, 100, 120} deg, N = 3 and n = 2 unless stated.

Every function returns a plain dict (times in milliseconds, wall clock, one thread unless
stated). ``run(quick=True)`` runs them all in well under 2 minutes.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from trackjam.control.assignment import build_assignment
from trackjam.control.assignment_exact import solve_assignment_exact
from trackjam.control.exact import BranchAndBound, solve_exact
from trackjam.control.grasp import solve_grasp
from trackjam.control.problem import build_problem
from trackjam.radio.antenna import AntennaModel
from trackjam.simulation.build import antenna_model, load_scenario
from trackjam.world.moves import displacement_set

#: displacement sets by their number of controls: (radial steps [m], N_phi, N_theta)
CONTROL_CASES = {79: ([1.0, 3.0, 5.0], 8, 8), 175: ([1.0, 3.0, 5.0], 16, 8), 11: ([3.0], 4, 8),
                 105: ([1.0, 3.0, 5.0, 7.0], 8, 8)}
OPENING_ANGLES_DEG = (60.0, 80.0, 100.0, 120.0)
LOW, HIGH = np.zeros(3), np.full(3, 100.0)


def paper_antenna(opening_deg: float) -> AntennaModel:
    s = load_scenario("paper-fig3")
    a = antenna_model(s)
    return dataclasses.replace(a, half_angle=float(np.deg2rad(opening_deg) / 2))


def draw_instance(rng: np.random.Generator, n_agents: int = 3, radius: float = 20.0):
    """(positions (N,3), aim (3,), opening angle [deg]) of one paper-like trial's first step."""
    x = rng.uniform(LOW, HIGH)
    d = rng.normal(size=(n_agents, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = radius * rng.uniform(size=(n_agents, 1)) ** (1 / 3)
    u = np.clip(x + r * d, LOW, HIGH)
    return u, x, float(rng.choice(OPENING_ANGLES_DEG))


def _problems(n_controls: int, instances: int, seed: int, n_agents: int = 3, at_least: int = 2,
              constraints: bool = True):
    D = displacement_set(*CONTROL_CASES[n_controls])
    rng = np.random.default_rng(seed)
    antennas = {a: paper_antenna(a) for a in OPENING_ANGLES_DEG}
    out = []
    for _ in range(instances):
        u, x, a = draw_instance(rng, n_agents)
        out.append(build_problem(u, x, D, antennas[a], LOW, HIGH, at_least, constraints))
    return out


def _stats(ms: list[float]) -> dict:
    a = np.asarray(ms)
    return {"median_ms": float(np.median(a)), "p95_ms": float(np.percentile(a, 95)), "max_ms": float(a.max())}


def _time_exact(P, max_nodes: int = 0):
    t = time.perf_counter()
    search = BranchAndBound(P)
    proven = search.run(None, max_nodes)
    return 1e3 * (time.perf_counter() - t), search.value, search.nodes, proven


def _warm():
    P = _problems(11, 1, 0)[0]
    solve_exact(P)
    solve_grasp(P, [np.random.default_rng(i) for i in range(3)], samples=10, iterations=2)


def bench_exact(n_controls: int = 79, instances: int = 200, seed: int = 0, constraints: bool = True) -> dict:
    """Time of the exact solver (branch and bound only, and with the problem's build)."""
    _warm()
    solve_ms, total_ms, nodes = [], [], []
    D = displacement_set(*CONTROL_CASES[n_controls])
    rng = np.random.default_rng(seed)
    antennas = {a: paper_antenna(a) for a in OPENING_ANGLES_DEG}
    for _ in range(instances):
        u, x, a = draw_instance(rng)
        t = time.perf_counter()
        P = build_problem(u, x, D, antennas[a], LOW, HIGH, 2, constraints)
        build = 1e3 * (time.perf_counter() - t)
        ms, _, k, _ = _time_exact(P)
        solve_ms.append(ms)
        total_ms.append(ms + build)
        nodes.append(k)
    return {
        "controls": n_controls, "instances": instances, "constraints": constraints,
        "solve": _stats(solve_ms), "build_and_solve": _stats(total_ms),
        "nodes_median": float(np.median(nodes)), "nodes_max": int(np.max(nodes)),
    }


def bench_grasp(n_controls: int = 79, instances: int = 20, seed: int = 0, samples: int = 10000,
                iterations: int = 100, threads: int = 1) -> dict:
    """Time per step of GRASP (all agents' searches) and its value relative to the optimum.

    The ratio is Xi(GRASP) / Xi(exact) over the instances whose optimum is > 0.
    """
    _warm()
    ms, ratios = [], []
    for k, P in enumerate(_problems(n_controls, instances, seed)):
        rngs = [np.random.default_rng([seed, k, j]) for j in range(P.n_agents)]
        t = time.perf_counter()
        g = solve_grasp(P, rngs, samples=samples, iterations=iterations, threads=threads)
        ms.append(1e3 * (time.perf_counter() - t))
        e = solve_exact(P)
        if e.objective > 0:
            ratios.append(g.objective / e.objective)
    r = np.asarray(ratios) if ratios else np.ones(1)
    return {
        "controls": n_controls, "instances": instances, "samples": samples, "iterations": iterations,
        "threads": threads, "time": _stats(ms), "ratio_mean": float(r.mean()), "ratio_worst": float(r.min()),
        "reached_optimum": float(np.mean(r >= 1 - 1e-12)), "instances_with_positive_optimum": len(ratios),
    }


def bench_scaling(n_agents=range(2, 7), instances: int = 10, seed: int = 0, samples: int = 10000,
                  iterations: int = 100, budget_s: float = 1.0, max_agents: int = 12,
                  grasp: bool = True) -> dict:
    """Exact and GRASP time per step for N agents at 79 controls (n = 2), and the largest N
    whose exact p95 time stays within ``budget_s`` (N grown past the table up to
    ``max_agents`` until it does not; a search is stopped after 2e7 nodes and counts as over)."""
    _warm()
    rows = []
    largest = 0
    N = min(n_agents)
    table = set(n_agents)
    while N <= max(max(table), max_agents):
        probs = _problems(79, instances, seed + N, n_agents=N)
        ex = [_time_exact(P, max_nodes=20_000_000) for P in probs]
        ex_ms = [e[0] for e in ex]
        proven = all(e[3] for e in ex)
        row = {"agents": N, "exact": _stats(ex_ms), "exact_proven": proven}
        if grasp and N in table:
            g_ms = []
            for k, P in enumerate(probs):
                rngs = [np.random.default_rng([seed, k, j]) for j in range(N)]
                t = time.perf_counter()
                solve_grasp(P, rngs, samples=samples, iterations=iterations)
                g_ms.append(1e3 * (time.perf_counter() - t))
            row["grasp"] = _stats(g_ms)
        rows.append(row)
        within = proven and row["exact"]["p95_ms"] <= 1e3 * budget_s
        if within:
            largest = N
        if N >= max(table) and not within:
            break
        N += 1
    return {"controls": 79, "instances": instances, "budget_s": budget_s, "rows": rows,
            "largest_exact_within_budget": largest}


def bench_belief(n_samples: int = 16, instances: int = 200, seed: int = 0, spread_m: float = 3.0,
                 n_controls: int = 79) -> dict:
    """`exact` planning over the belief (N = 3, n = 2): the objective averaged over
    ``n_samples`` positions drawn from a Gaussian of ``spread_m`` [m] per axis around the aim,
    equal weights (a resampled particle set); time of build and solve per step."""
    _warm()
    D = displacement_set(*CONTROL_CASES[n_controls])
    antennas = {a: paper_antenna(a) for a in OPENING_ANGLES_DEG}
    rng = np.random.default_rng([seed, n_samples])
    ms, nodes, proven = [], [], []
    for _ in range(instances):
        u, x, a = draw_instance(rng)
        xs = np.clip(x + rng.normal(0, spread_m, (n_samples, 3)), LOW, HIGH)
        t = time.perf_counter()
        P = build_problem(u, x, D, antennas[a], LOW, HIGH, 2, True, samples=xs)
        sol = solve_exact(P, time_limit_s=None)
        ms.append(1e3 * (time.perf_counter() - t))
        nodes.append(sol.nodes)
        proven.append(sol.optimal)
    return {"controls": n_controls, "samples": n_samples, "spread_m": spread_m, "instances": instances,
            "build_and_solve": _stats(ms), "nodes_median": float(np.median(nodes)),
            "nodes_max": int(np.max(nodes)), "proven_optimal": float(np.mean(proven))}


def bench_budget(n_agents=(6, 8), instances: int = 20, seed: int = 0, time_limit_s: float = 1.0) -> dict:
    """`exact` under its time budget (``control.time_limit_s``) at 79 controls, n = 2: time per
    step (build and solve), the share of steps proven optimal, and the certified gaps left
    (optimum - plan <= gap, in units of Xi) over the steps that were not."""
    _warm()
    D = displacement_set(*CONTROL_CASES[79])
    antennas = {a: paper_antenna(a) for a in OPENING_ANGLES_DEG}
    rows = []
    for N in n_agents:
        rng = np.random.default_rng([seed, N])
        ms, gaps, proven, values = [], [], [], []
        for _ in range(instances):
            u, x, a = draw_instance(rng, N)
            t = time.perf_counter()
            P = build_problem(u, x, D, antennas[a], LOW, HIGH, 2, True)
            sol = solve_exact(P, time_limit_s=time_limit_s)
            ms.append(1e3 * (time.perf_counter() - t))
            gaps.append(sol.gap)
            proven.append(sol.optimal)
            values.append(sol.objective)
        g = np.asarray(gaps)
        rows.append({
            "agents": N, "instances": instances, "step_ms_median": float(np.median(ms)),
            "step_ms_max": float(np.max(ms)), "proven_optimal": float(np.mean(proven)),
            "gap_median": float(np.median(g)), "gap_max": float(g.max()),
            "xi_median": float(np.median(values)),
        })
    return {"controls": 79, "time_limit_s": time_limit_s, "rows": rows}


def draw_targets(rng: np.random.Generator, n_targets: int, n_agents: int, spread: float = 15.0,
                 radius: float = 20.0):
    """(positions (N,3), aims (K,3), opening angle [deg]) of a swarm's step: a centre uniform in
    the area, K aims uniform in a ``spread`` [m] ball around it, N agents in a ``radius`` ball."""
    u, x, a = draw_instance(rng, n_agents, radius)
    d = rng.normal(size=(n_targets, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    aims = np.clip(x + spread * rng.uniform(size=(n_targets, 1)) ** (1 / 3) * d, LOW, HIGH)
    return u, aims, a


def bench_assignment(n_targets: int = 2, n_agents: int = 4, instances: int = 200, seed: int = 0,
                     objective: str = "sum", n_controls: int = 79, at_least: int = 2) -> dict:
    """`exact` for K targets (each agent also chooses the target it serves), unbudgeted: time of
    build and solve per step and of the search alone, nodes, share proven optimal."""
    _warm()
    D = displacement_set(*CONTROL_CASES[n_controls])
    antennas = {a: paper_antenna(a) for a in OPENING_ANGLES_DEG}
    rng = np.random.default_rng([seed, n_targets, n_agents])
    warm = build_assignment(*draw_targets(rng, n_targets, n_agents)[:2], D, antennas[80.0], LOW, HIGH,
                                        at_least, True, objective)
    solve_assignment_exact(warm)
    total_ms, solve_ms, nodes, proven = [], [], [], []
    for _ in range(instances):
        u, aims, a = draw_targets(rng, n_targets, n_agents)
        t = time.perf_counter()
        P = build_assignment(u, aims, D, antennas[a], LOW, HIGH, at_least, True, objective)
        t1 = time.perf_counter()
        sol = solve_assignment_exact(P)
        t2 = time.perf_counter()
        total_ms.append(1e3 * (t2 - t))
        solve_ms.append(1e3 * (t2 - t1))
        nodes.append(sol.nodes)
        proven.append(sol.optimal)
    return {"targets": n_targets, "agents": n_agents, "at_least": at_least, "objective": objective,
            "controls": n_controls, "instances": instances, "build_and_solve": _stats(total_ms),
            "solve": _stats(solve_ms), "nodes_median": float(np.median(nodes)), "nodes_max": int(np.max(nodes)),
            "proven_optimal": float(np.mean(proven))}


def bench_close_in(instances: int = 200, seed: int = 0, threshold: float = 0.05, n_controls: int = 105,
                   radius: float = 20.0) -> dict:
    """``control.close_in``: the exact step (problem build + the searches of
    :func:`trackjam.control.distributed.own_searches`) with and without closing in, on the
    paper-like instances (agents in a ``radius`` m ball around the aim) with 7 m steps (105
    controls), the control set closing in is for. Reports how many instances closed in (their
    constrained optimum was worth Xi < ``threshold`` and the optimum without Eq. (13) moves
    elsewhere), the times of those both ways (timed in alternating order) and the time closing
    in added, instance by instance."""
    from trackjam.control.distributed import own_searches

    _warm()
    D = displacement_set(*CONTROL_CASES[n_controls])
    rng = np.random.default_rng(seed)
    antennas = {a: paper_antenna(a) for a in OPENING_ANGLES_DEG}
    plain_ms, closed_ms = [], []
    for i in range(instances):
        u, x, a = draw_instance(rng, radius=radius)
        times, closed = {}, False
        for tau in ((None, threshold) if i % 2 == 0 else (threshold, None)):
            t = time.perf_counter()
            P = build_problem(u, x, D, antennas[a], LOW, HIGH, 2, True)
            (sol, _), = own_searches(P, "exact", [0], [rng], 0, 0, 2, 1, 1.0, 0, tau)
            times[tau] = 1e3 * (time.perf_counter() - t)
            closed = closed or sol.closed_in
        if closed:
            plain_ms.append(times[None])
            closed_ms.append(times[threshold])
    added = np.subtract(closed_ms, plain_ms) if closed_ms else np.array([np.nan])
    return {"controls": n_controls, "instances": instances, "threshold": threshold, "radius_m": radius,
            "closed_in": len(closed_ms), "without": _stats(plain_ms or [np.nan]), "with": _stats(closed_ms or [np.nan]),
            "added_median_ms": float(np.median(added))}


def run(quick: bool = True, seed: int = 0) -> dict:
    """All the control benchmarks; ``quick`` keeps the total well under 2 minutes."""
    if quick:
        return {
            "exact_79": bench_exact(79, 100, seed),
            "exact_175": bench_exact(175, 50, seed),
            "grasp_79": bench_grasp(79, 8, seed),
            "scaling": bench_scaling(range(2, 7), 4, seed, samples=2000, iterations=20, max_agents=8),
            "exact_budget": bench_budget((6, 8), 5, seed),
            "exact_belief_16": bench_belief(16, 40, seed),
            "exact_belief_32": bench_belief(32, 20, seed),
            "assignment_k2_n4_sum": bench_assignment(2, 4, 40, seed, "sum"),
            "assignment_k2_n4_min": bench_assignment(2, 4, 40, seed, "min"),
            "exact_close_in": bench_close_in(40, seed),
        }
    return {
        "exact_79": bench_exact(79, 1000, seed),
        "exact_175": bench_exact(175, 500, seed),
        "exact_79_unconstrained": bench_exact(79, 1000, seed, constraints=False),
        "grasp_79": bench_grasp(79, 50, seed),
        "grasp_79_threads": bench_grasp(79, 50, seed, threads=2),
        "scaling": bench_scaling(range(2, 7), 20, seed),
        "exact_budget": bench_budget((6, 8), 20, seed),
        "exact_belief_16": bench_belief(16, 200, seed),
        "exact_belief_32": bench_belief(32, 200, seed),
        "assignment_k2_n4_sum": bench_assignment(2, 4, 200, seed, "sum"),
        "assignment_k2_n4_min": bench_assignment(2, 4, 200, seed, "min"),
        "assignment_k3_n5_sum": bench_assignment(3, 5, 100, seed, "sum"),
        "exact_close_in": bench_close_in(200, seed),
    }


def main(argv: list[str] | None = None) -> None:
    """``python -m trackjam.benchmarks.control [--full]``: the control figures alone, as JSON
    (``--help`` ran the benchmarks, and an unknown argument such as ``--ful`` was ignored)."""
    import argparse
    import json

    parser = argparse.ArgumentParser(
        prog="python -m trackjam.benchmarks.control", allow_abbrev=False,
        description="Run the control benchmarks of `trackjam bench` alone and print their figures as JSON.",
    )
    parser.add_argument("--full", action="store_true", help="the full repetitions (minutes) instead of the quick ones")
    args = parser.parse_args(argv)
    print(json.dumps(run(quick=not args.full), indent=1))


if __name__ == "__main__":
    main()
