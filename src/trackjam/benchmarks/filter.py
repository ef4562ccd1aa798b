"""Timing of one Bernoulli filter step (predict + update) at the default particle counts."""

from __future__ import annotations

import time

import numpy as np

from trackjam.radio.measurement import clutter_bounds, h
from trackjam.simulation.build import build, load_scenario



def timing_ms(times: np.ndarray) -> dict:
    """Median, 95th percentile, min and max of per-step wall times [ms]."""
    return {"median_ms": float(np.median(times)), "p95_ms": float(np.percentile(times, 95)),
            "min_ms": float(times.min()), "max_ms": float(times.max())}

def bench_filter_step(repeats: int = 50, seed: int = 0, particles: int = 10_000, birth_particles: int = 2_000,
                      mode: tuple[float, float] | None = None,
                      resampling: tuple[int, float] | None = None,
                      visibility: tuple[float, float, bool] | None = None) -> dict:
    """Median and 95th percentile wall time [ms] of ``predict()`` + ``update()`` with 4 measurements
    (1 from a hovering target 5.2 m ahead of the agent, 3 clutter points drawn afresh each step), after a warm-up step so that numba's
    compilation (cached on disk) is not counted.

    Beside the times it reports what the timed filter did, so that a broken filter cannot pass
    for a fast one: the particles it weighed in its last update (survivors, young component and
    births), its final existence and the distance of its final mean from the target.
    ``mode`` = (radius, mass) times the filter with ``filter.mode`` (its estimate at the mode),
    ``resampling`` = (memory, jitter) with ``filter.reserve_memory`` and ``filter.velocity_jitter``,
    ``visibility`` = (hide, reappear, per_particle) with the hidden-target mode ``filter.visibility``."""
    n_meas = 4
    fields = {} if mode is None else {"filter__mode": {"radius": mode[0], "mass": mode[1]}}
    if resampling is not None:
        fields |= {"filter__reserve_memory": resampling[0], "filter__velocity_jitter": resampling[1]}
    if visibility is not None:
        fields |= {"filter__visibility": dict(zip(("hide", "reappear", "per_particle"), visibility))}
    c = build(load_scenario("paper-fig3", filter__particles=particles, filter__birth_particles=birth_particles,
                            **fields))
    rng = np.random.default_rng(seed)
    f = c.make_filter(rng)
    x = np.array(c.target.initial, dtype=float)
    x[3:] = 0.0  # a hovering target: its scans and the filter's motion model agree
    u = x[:3] - np.array([3.0, 3.0, 3.0])
    level_w = float(c.antenna.levels_w[-1])
    bounds = clutter_bounds(c.antenna.max_range)

    def scan() -> np.ndarray:
        z = h(x, u) + rng.normal(0.0, 1.0, 3) * np.asarray(c.noise_std)
        return np.vstack([z, rng.uniform(bounds[:, 0], bounds[:, 1], size=(n_meas - 1, 3))])

    f.predict()
    f.update(scan(), u, x[:3], level_w)  # warm-up: compile or load the numba cache
    times = np.empty(repeats)
    for r in range(repeats):
        Z = scan()
        t0 = time.perf_counter()
        f.predict()
        est = f.update(Z, u, x[:3], level_w)
        times[r] = (time.perf_counter() - t0) * 1e3
    return {
        **timing_ms(times),
        "repeats": repeats,
        "seed": seed,
        "particles": particles,
        "birth_particles": birth_particles,
        "weighed": f.weighed,
        "measurements": n_meas,
        "birth": f.birth,
        "mode": None if f.mode is None else list(f.mode),
        "reserve_memory": f.reserve_memory,
        "velocity_jitter": f.velocity_jitter,
        "visibility": None if f.visibility is None else [*f.visibility, f.per_particle],
        "existence": float(est.existence),
        "error_m": float(np.linalg.norm(est.mean[:3] - x[:3])),
    }
