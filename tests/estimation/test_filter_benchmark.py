"""The filter-step benchmark (trackjam.benchmarks.filter) times a filter that works: its figures
are ordered and finite, the timed filter weighed the whole particle budget each step, and it
tracked the target it was shown."""

import math

import pytest

from trackjam.benchmarks.filter import bench_filter_step


@pytest.mark.parametrize("particles, birth_particles", [(10_000, 2_000), (3_000, 500)])
def test_bench_filter_step_times_a_filter_that_tracks(particles, birth_particles):
    r = bench_filter_step(repeats=5, seed=1, particles=particles, birth_particles=birth_particles)
    times = [r["min_ms"], r["median_ms"], r["p95_ms"], r["max_ms"]]
    assert all(math.isfinite(t) and t > 0 for t in times)
    assert times == sorted(times)
    # survivors (with the young component) and births: n + n_b particles weighed per update
    assert r["weighed"] == particles + birth_particles
    # a target 5.2 m ahead detected at p_D = 0.95 every step: confirmed, and within a metre or so
    assert r["existence"] > 0.99
    assert r["error_m"] < 1.5
    assert r["particles"] == particles and r["measurements"] == 4 and r["birth"] == "uniform"


def test_bench_filter_step_with_the_mode_estimate_times_that_filter():
    r = bench_filter_step(repeats=5, seed=1, particles=3_000, birth_particles=500, mode=(5.0, 0.2))
    assert r["mode"] == [5.0, 0.2] and r["existence"] > 0.99
    assert r["error_m"] < 1.5  # the mode of a filter locked on its target is the target
    assert bench_filter_step(repeats=2, seed=1, particles=3_000, birth_particles=500)["mode"] is None
