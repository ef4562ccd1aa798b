"""The filter-step benchmark (trackjam.benchmarks.filter) reports its numbers and parameters."""

from trackjam.benchmarks.filter import bench_filter_step


def test_bench_filter_step_reports_timings_and_parameters():
    r = bench_filter_step(repeats=3, seed=1)
    assert r["particles"] == 10_000 and r["birth_particles"] == 2_000 and r["measurements"] == 4
    assert 0 < r["median_ms"] <= r["p95_ms"]
    assert r["repeats"] == 3 and r["seed"] == 1
