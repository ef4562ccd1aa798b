"""Benchmark of the learning environment: env steps per second with uniform random actions on
the paper's Fig. 3 scenario (`paper-fig3`: N = 3, 79 controls, 10,000 + 2,000 particles) and on
`swarm-3` (several targets: N = 5, K = 3, the swarm engine's LMB filters)."""

from __future__ import annotations

import time

import numpy as np



def name(preset: str) -> str:
    """The benchmark's title for ``preset``."""
    return f"env steps, random actions, {preset}"


NAME = name("paper-fig3")


def bench_env(episodes: int = 3, preset: str = "paper-fig3", overrides: tuple[str, ...] = ()) -> dict:
    """Wall and CPU time of ``env.step`` over ``episodes`` episodes (seeds 1..episodes), after a
    warm-up episode that loads numba's cache (``overrides``: ``--set`` style, for the tests). CPU time is reported beside wall time because on a
    shared machine it is the better estimate of the time alone."""
    try:
        from trackjam.env import parallel_env, random_policy
    except ImportError as err:
        return {"name": name(preset), "skipped": str(err)}
    from trackjam.simulation.build import load_scenario

    env = parallel_env(load_scenario(preset, list(overrides)))
    policy = random_policy(env)

    def episode(seed: int) -> tuple[list[float], float]:
        obs, _ = env.reset(seed=seed)
        policy.reset(seed)
        wall = []
        c0 = time.process_time()
        while env.agents:
            actions = policy(obs)
            t0 = time.perf_counter()
            obs, *_ = env.step(actions)
            wall.append(time.perf_counter() - t0)
        return wall, time.process_time() - c0

    episode(0)
    walls, cpu = [], 0.0
    for seed in range(1, episodes + 1):
        w, c = episode(seed)
        walls += w
        cpu += c
    walls = np.array(walls)
    return {
        "name": name(preset),
        "episodes": episodes,
        "steps": int(walls.size),
        "steps_per_s": float(walls.size / walls.sum()),
        "step_ms_median": 1000 * float(np.median(walls)),
        "step_ms_p95": 1000 * float(np.percentile(walls, 95)),
        "cpu_ms_per_step": 1000 * cpu / walls.size,
    }
