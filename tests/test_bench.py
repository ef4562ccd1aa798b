"""`trackjam bench` prints a table for every figure it measured, nested ones included, and
writes the same figures as JSON (no timing is asserted: only that the figures are sane)."""

import json

import pytest
from typer.testing import CliRunner

from trackjam.benchmarks.control import bench_budget, bench_exact, bench_scaling
from trackjam.benchmarks.report import _print, cell, flatten
from trackjam.cli import app


def _timings(d: dict, path: str = ""):
    """Every (where, {median_ms, p95_ms, ...}) statistics dict inside a benchmark result."""
    if isinstance(d, dict):
        if "median_ms" in d:
            yield path, d
        for k, v in d.items():
            yield from _timings(v, f"{path}.{k}")
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield from _timings(v, f"{path}[{i}]")


def _sane(stats: dict) -> None:
    assert 0 < stats["median_ms"] <= stats["p95_ms"], stats
    if "max_ms" in stats:
        assert stats["p95_ms"] <= stats["max_ms"], stats


def test_flatten_and_cells():
    assert flatten({"a": 1, "b": {"c": 2.0, "d": {"e": None}}, "f": [1]}) == {"a": 1, "b.c": 2.0, "b.d.e": None, "f": [1]}
    assert [cell(v) for v in (1.23456, True, None, 7, "x")] == ["1.235", "yes", "-", "7", "x"]


def test_the_report_prints_every_nested_timing_and_the_scaling_rows(capsys):
    rows = [
        {"name": "exact_11", **bench_exact(11, instances=5)},
        {"name": "scaling", **bench_scaling(range(2, 4), instances=2, samples=50, iterations=2, max_agents=3)},
        {"name": "exact_budget", **bench_budget((3,), 2, time_limit_s=0.5)},
    ]
    _print("control", rows)
    out = capsys.readouterr().out
    for row in rows:
        for where, stats in _timings(row):
            _sane(stats)
    exact = flatten(rows[0])
    for key in ("solve.median_ms", "solve.p95_ms", "build_and_solve.median_ms", "nodes_median"):
        line = next(ln for ln in out.splitlines() if f" {key} " in ln)
        assert cell(exact[key]) in line
    assert "{" not in out and "}" not in out  # no raw dict anywhere
    scaling_rows = rows[1]["rows"]
    assert "scaling: rows" in out and "exact.p95_ms" in out and "grasp.median_ms" in out
    for r in scaling_rows:
        line = next(ln for ln in out.splitlines() if ln.strip(" │┃|").startswith(f"{r['agents']} "))
        assert cell(r["exact"]["median_ms"]) in line and cell(r["exact_proven"]) in line


def test_bench_filter_group_prints_and_writes_its_timings(tmp_path):
    out = tmp_path / "bench.json"
    r = CliRunner().invoke(app, ["bench", "--quick", "--only", "filter", "--json", str(out)])
    assert r.exit_code == 0, r.output
    data = json.loads(out.read_text())
    assert set(data) == {"machine", "quick", "filter", "calibration"} and data["quick"] is True
    cal = data["calibration"]
    assert cal["workload"].startswith("numpy sort") and cal["start_ms"] > 0 and cal["end_ms"] > 0
    assert f"{cal['start_ms']:.1f} ms" in r.output and "calibration at the end" in r.output
    row = data["filter"][0]
    _sane(row)
    assert row["repeats"] == 20 and data["machine"]["cores"] >= 1
    options = next(r for r in data["filter"] if "reserve_memory 1" in r["name"])
    _sane(options)
    assert (options["reserve_memory"], options["velocity_jitter"]) == (1, 0.5)
    assert (row["reserve_memory"], row["velocity_jitter"]) == (0, 0.0)
    hidden = [r for r in data["filter"] if "hidden-target mode" in r["name"]]
    for r_ in hidden:  # a filter that lost the hovering target cannot pass for a fast one
        _sane(r_)
        assert r_["existence"] > 0.9 and r_["error_m"] < 2.0, r_
    assert [r_["visibility"] for r_ in hidden] == [[0.05, 0.25, False], [0.05, 0.25, True]]
    assert row["visibility"] is None
    for key in ("median_ms", "p95_ms"):
        line = next(ln for ln in r.output.splitlines() if f" {key} " in ln)
        assert cell(row[key]) in line


def test_a_skipped_benchmarks_bracketed_text_is_printed_literally(monkeypatch):
    # without the env extra the env group says how to install it; rich read "[env]" as markup
    # and printed `pip install "trackjam"`
    from trackjam.benchmarks import env

    skipped = ('trackjam.env needs the env extra: pip install ".[env]" from the trackjam checkout '
               "(No module named 'pettingzoo')")
    monkeypatch.setattr(env, "bench_env", lambda episodes, **_: {"name": f"{env.NAME} [x]", "skipped": skipped,
                                                           "rows": [{"[bold]k": "[v]"}]})
    r = CliRunner().invoke(app, ["bench", "--quick", "--only", "env"])
    assert r.exit_code == 0, r.output
    assert 'pip install ".[env]"' in r.output
    assert f"{env.NAME} [x]" in r.output and "[bold]k" in r.output and "[v]" in r.output


def test_unknown_bench_group_exits_2():
    r = CliRunner().invoke(app, ["bench", "--only", "everything"])
    assert r.exit_code == 2


@pytest.mark.parametrize("where, words", [("folder", "is a folder"), ("missing/b.json", "is not an existing folder"),
                                         ("afile/b.json", "afile is a file, not a folder")])
def test_a_bad_json_path_is_refused_before_any_benchmark(tmp_path, where, words):
    (tmp_path / "folder").mkdir()
    (tmp_path / "afile").write_text("a user's file")
    r = CliRunner().invoke(app, ["bench", "--quick", "--only", "filter", "--json", str(tmp_path / where)])
    assert r.exit_code == 2 and words in r.output and "running" not in r.output


def test_the_run_benchmark_times_a_several_target_preset_through_the_swarm_engine():
    from trackjam.benchmarks.run import bench_run

    r = bench_run("exact", repeats=1, steps=2, preset="swarm-3")
    assert r["name"] == "run swarm-3 (exact)" and r["steps"] == 2 and r["repeats"] == 1
    assert r["step_ms_median"] >= r["solve_ms_median"] > 0.0


def test_the_control_module_prints_its_help_and_refuses_an_unknown_argument(capsys):
    import subprocess
    import sys

    from trackjam.benchmarks import control

    # --help ran the quick benchmarks (16 s) and printed their JSON
    r = subprocess.run([sys.executable, "-m", "trackjam.benchmarks.control", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.startswith("usage: python -m trackjam.benchmarks.control")
    assert "--full" in r.stdout and "exact_79" not in r.stdout
    for argv in (["--ful"], ["--full", "extra"]):  # was ignored; --ful is no abbreviation of --full either
        with pytest.raises(SystemExit) as exit:
            control.main(argv)
        assert exit.value.code == 2
        assert f"unrecognized arguments: {argv[-1]}" in capsys.readouterr().err
