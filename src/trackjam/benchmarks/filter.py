"""Timing of one Bernoulli filter step (predict + update) at the paper's particle counts."""

from __future__ import annotations

import time

import numpy as np

from trackjam.config import load_scenario
from trackjam.estimation.bernoulli import BernoulliFilter
from trackjam.radio.measurement import h


def bench_filter_step(repeats: int = 50, seed: int = 0) -> dict:
    """Median and 95th percentile wall time [ms] of ``predict()`` + ``update()`` with 10,000
    particles, 2,000 birth particles and 4 measurements (1 from the target, 3 clutter), after
    a warm-up step so that numba's compilation (cached on disk) is not counted."""
    particles, birth_particles, n_meas = 10_000, 2_000, 4
    s = load_scenario("paper-fig3", filter__particles=particles, filter__birth_particles=birth_particles)
    rng = np.random.default_rng(seed)
    f = BernoulliFilter(s, rng)
    x = np.array(s.target.initial, dtype=float)
    u = x[:3] - np.array([3.0, 3.0, 3.0])
    level_w = float(s.antenna.levels_w[-1])
    clutter = np.array([[10.0, 0.5, 1.0], [25.0, -2.0, 2.0], [5.0, 3.0, 0.3]])

    def scan() -> np.ndarray:
        z = h(x, u) + rng.normal(0.0, 1.0, 3) * np.asarray(s.sensor.noise_std)
        return np.vstack([z, clutter])[:n_meas]

    f.predict()
    f.update(scan(), u, x[:3], level_w)  # warm-up: compile or load the numba cache
    times = np.empty(repeats)
    for r in range(repeats):
        Z = scan()
        t0 = time.perf_counter()
        f.predict()
        f.update(Z, u, x[:3], level_w)
        times[r] = (time.perf_counter() - t0) * 1e3
    return {
        "median_ms": float(np.median(times)),
        "p95_ms": float(np.percentile(times, 95)),
        "repeats": repeats,
        "seed": seed,
        "particles": particles,
        "birth_particles": birth_particles,
        "measurements": n_meas,
        "birth": s.filter.birth,
    }
