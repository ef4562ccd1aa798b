"""Timing of one LMB filter step (predict + update) with three targets at the paper's particle
counts per track (several targets, ours)."""

from __future__ import annotations

import math
import time

import numpy as np

from trackjam.benchmarks.filter import timing_ms
from trackjam.estimation.lmb import LMBFilter, LMBParams
from trackjam.radio.antenna import axis_of, detection_probability
from trackjam.radio.measurement import sample_scan_multi
from trackjam.simulation.build import antenna_model, filter_params, load_scenario

TARGETS = 3
BIRTH_RATE = 0.1  # lambda_B of the timed filter
BIRTH_EXISTENCE_MAX = 0.1  # r_B^max


def bench_lmb_step(repeats: int = 50, seed: int = 0, association: str = "gibbs") -> dict:
    """Median and 95th percentile wall time [ms] of ``predict()`` + ``update()`` of one agent's
    LMB filter watching three hovering targets 5.2 m ahead (30 deg apart around the antenna's
    axis, each detected with the paper's p_D there) in the paper's clutter, at ``paper-fig3``'s
    particle counts per track, after warm-up steps that compile numba's kernels (cached on
    disk) and let the tracks be confirmed.

    Beside the times it reports what the timed filter held, so that a broken filter cannot pass
    for a fast one: its tracks, the confirmed ones (r > 0.5) and the largest distance of a
    confirmed track from its nearest target."""
    s = load_scenario("paper-fig3")
    fp, ant = filter_params(s), antenna_model(s)
    p = LMBParams(
        survival_prob=fp.survival_prob, particles=fp.particles, birth_particles=fp.birth_particles,
        birth_rate=BIRTH_RATE, birth_existence_max=BIRTH_EXISTENCE_MAX, birth_speed=fp.birth_speed,
        accel_var=fp.accel_var, walls=fp.walls, low=fp.low, high=fp.high, noise_std=fp.noise_std,
        clutter_rate=fp.clutter_rate, association=association,
    )
    rng_truth, rng_filter = (np.random.default_rng(q) for q in np.random.SeedSequence(seed).spawn(2))
    f = LMBFilter(p, ant, rng_filter)
    u = np.array([30.0, 30.0, 30.0])
    aim = u + np.array([3.0, 3.0, 3.0])
    axis = axis_of(u, aim)
    side = np.cross(axis, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    up = np.cross(side, axis)
    tilt = math.radians(30.0)
    dirs = [axis] + [math.cos(tilt) * axis + math.sin(tilt) * v for v in (side, up)]
    X = np.array([u + 5.2 * d for d in dirs])
    p_d = detection_probability(X, u, aim, ant.l_max, ant)

    def step() -> float:
        Z, _ = sample_scan_multi(rng_truth, X, u, p_d, fp.noise_std, fp.clutter_rate, ant.max_range)
        t0 = time.perf_counter()
        f.predict()
        f.update(Z, u, aim, ant.l_max)
        return (time.perf_counter() - t0) * 1e3

    for _ in range(5):
        step()
    times = np.array([step() for _ in range(repeats)])
    confirmed = [e for e in f.estimates() if e.existence > 0.5]
    errors = [np.min(np.linalg.norm(X - e.mean[:3], axis=1)) for e in confirmed]
    return {
        **timing_ms(times),
        "repeats": repeats,
        "seed": seed,
        "association": association,
        "targets": TARGETS,
        "particles_per_track": fp.particles,
        "birth_particles": fp.birth_particles,
        "tracks": len(f.tracks),
        "confirmed": len(confirmed),
        "max_error_m": float(max(errors)) if errors else float("nan"),
    }
