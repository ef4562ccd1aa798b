"""`trackjam bench` has an env group that measures env steps with random actions (no timing is
asserted, only that the figures are consistent)."""

from trackjam.benchmarks.env import bench_env
from trackjam.benchmarks.report import _groups


def test_env_group_is_registered():
    assert "env" in _groups(quick=True)


def test_bench_env_counts_every_step_of_every_episode():
    row = bench_env(episodes=2, overrides=("steps=3", "filter.particles=300", "filter.birth_particles=50"))
    assert row["episodes"] == 2 and row["steps"] == 6
    assert 0 < row["step_ms_median"] <= row["step_ms_p95"]
    assert row["steps_per_s"] > 0 and row["cpu_ms_per_step"] > 0


def test_bench_env_runs_the_several_target_environment_too():
    from trackjam.benchmarks.env import name

    row = bench_env(episodes=1, preset="swarm-3", overrides=("steps=2", "filter.particles=200", "filter.birth_particles=50"))
    assert row["name"] == name("swarm-3") != name("paper-fig3")
    assert row["episodes"] == 1 and row["steps"] == 2
    assert 0 < row["step_ms_median"] <= row["step_ms_p95"]
