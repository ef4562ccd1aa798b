"""The K-target control benchmark's figures are consistent (no timing is asserted): unbudgeted,
every search is proven optimal."""

from trackjam.benchmarks.control import bench_assignment


def test_assignment_bench_proves_every_instance():
    row = bench_assignment(2, 3, instances=3, seed=1, objective="min", n_controls=11)
    assert row["proven_optimal"] == 1.0 and row["nodes_median"] >= 1
    assert (row["targets"], row["agents"], row["objective"]) == (2, 3, "min")
    t = row["build_and_solve"]
    assert 0 < t["median_ms"] <= t["p95_ms"] <= t["max_ms"]
    assert row["solve"]["median_ms"] <= t["max_ms"]
