"""`trackjam bench` runs its groups and writes what it measured (no timing is asserted)."""

import json

from typer.testing import CliRunner

from trackjam.cli import app


def test_bench_filter_group_writes_json(tmp_path):
    out = tmp_path / "bench.json"
    r = CliRunner().invoke(app, ["bench", "--quick", "--only", "filter", "--json", str(out)])
    assert r.exit_code == 0, r.output
    data = json.loads(out.read_text())
    row = data["filter"][0]
    assert row["particles"] == 10000 and row["birth_particles"] == 2000 and row["measurements"] == 4
    assert 0 < row["median_ms"] <= row["p95_ms"]
    assert data["machine"]["cores"] >= 1


def test_unknown_bench_group_exits_2():
    r = CliRunner().invoke(app, ["bench", "--only", "everything"])
    assert r.exit_code == 2
