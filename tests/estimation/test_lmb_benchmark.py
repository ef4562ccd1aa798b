"""The LMB-step benchmark (trackjam.benchmarks.lmb) times a filter that works: its figures are
ordered and finite, and the timed filter holds the three targets it was shown, each once."""

import math

import pytest

from trackjam.benchmarks.lmb import bench_lmb_step


@pytest.mark.parametrize("association", ["gibbs", "ranked"])
def test_bench_lmb_step_times_a_filter_that_tracks(association):
    r = bench_lmb_step(repeats=5, seed=0, association=association)
    times = [r["min_ms"], r["median_ms"], r["p95_ms"], r["max_ms"]]
    assert all(math.isfinite(t) and t > 0 for t in times)
    assert times == sorted(times)
    assert r["confirmed"] == r["targets"] == 3
    assert r["max_error_m"] < 1.5  # each target 5.2 m ahead, seen at p_D = 0.95: within a metre or so
    assert r["tracks"] >= r["confirmed"] and r["association"] == association
    assert r["particles_per_track"] == 10_000 and r["birth_particles"] == 2_000
