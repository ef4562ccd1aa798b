"""The control benchmarks' figures are consistent (no timing is asserted): a belief search is
proven optimal when unbounded, and a budgeted one reports shares and gaps in range."""

from trackjam.benchmarks.control import bench_belief, bench_budget


def test_belief_bench_proves_every_instance():
    row = bench_belief(n_samples=4, instances=3, seed=1)
    assert row["proven_optimal"] == 1.0 and row["nodes_median"] >= 1 and row["samples"] == 4
    t = row["build_and_solve"]
    assert 0 < t["median_ms"] <= t["p95_ms"] <= t["max_ms"]


def test_budget_bench_reports_shares_and_gaps_in_range():
    out = bench_budget((4,), instances=3, seed=1, time_limit_s=0.05)
    (row,) = out["rows"]
    assert row["agents"] == 4 and 0.0 <= row["proven_optimal"] <= 1.0
    assert 0.0 <= row["gap_median"] <= row["gap_max"] <= 1.0
    if row["proven_optimal"] == 1.0:
        assert row["gap_max"] == 0.0


def test_close_in_bench_times_the_instances_that_closed_in():
    from trackjam.benchmarks.control import bench_close_in

    row = bench_close_in(instances=30, seed=0)
    assert row["controls"] == 105 and 0 < row["closed_in"] <= 30  # some of these instances close in
    for way in ("without", "with"):
        t = row[way]
        assert 0 < t["median_ms"] <= t["p95_ms"] <= t["max_ms"]
    assert row["added_median_ms"] == row["added_median_ms"]  # a number: the instances that closed in were timed
