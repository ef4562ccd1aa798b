"""The README's code runs as written: its Python blocks, and the swarm-3 table the docs show.

The quick start's table is held to the run in tests/test_cli.py; here every ```python block of the
README is executed, in a fresh interpreter and an empty folder, exactly as a user would paste it
(the blocks that continue an earlier one run after it), so a renamed function, a changed
signature or an undefined name in the README fails the suite.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from readme_tables import README, SEVERAL_TARGETS, closing_table_rows
from typer.testing import CliRunner

from trackjam.cli import app

BLOCKS = re.findall(r"^```python\n(.*?)^```", README, re.S | re.M)


def _block(first_line_part: str) -> str:
    found = [b for b in BLOCKS if first_line_part in b]
    assert len(found) == 1, f"README: {len(found)} python blocks contain {first_line_part!r}"
    return found[0]


def _run(code: str, cwd: Path) -> str:
    r = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return r.stdout


def test_the_readme_has_the_python_blocks_these_tests_run():
    # eight blocks: the API, step by step, reading a run's files, the environment, the comparison
    # by seed, the environment on several targets, its observations scaled with a small frame, an
    # experiment of one's own; a new block must be added to a test below
    assert len(BLOCKS) == 8


def test_the_block_that_reads_a_runs_files_runs_as_written_and_agrees_with_the_summary(tmp_path):
    import json

    out = _run(_block("pq.read_table(\"runs/read-me/steps.parquet\")"), tmp_path)
    held = float(re.search(r"held share: ([\d.]+)", out).group(1))
    reported = int(re.search(r"steps reported: (\d+)", out).group(1))
    summary = json.loads((tmp_path / "runs" / "read-me" / "summary.json").read_text())
    assert held == pytest.approx(summary["held_share"]) and reported == summary["confirmed_steps"]


def test_the_python_api_blocks_run_as_written(tmp_path):
    api = _block("write_run(result")
    stepwise = _block("sim = Simulation(s)")
    out = _run(api + "\n" + stepwise + "\nprint('steps', len(result.steps['t']), sim.done)\n", tmp_path)
    first, last = out.strip().splitlines()[0], out.strip().splitlines()[-1]
    ospa, incidents = first.split(" ", 1)
    assert float(ospa) >= 0 and re.fullmatch(r"\[\d+(, \d+)*\]", incidents)  # the mean OSPA, incidents per agent
    assert last == "steps 30 True"
    written = {p.name for p in (tmp_path / "runs" / "mine").iterdir()}
    assert {"steps.parquet", "agents.parquet", "summary.json"} <= written


def test_the_learning_environment_blocks_run_as_written(tmp_path):
    env_block = _block('parallel_env(trackjam.load_scenario("paper-fig3")')
    compare = _block("rollout(env, my_policy, seeds)")
    code = env_block + "\n" + compare + "\nprint(len(paired), result.summary['steps'])\n"
    out = _run(code, tmp_path)
    n, steps = out.split()
    assert int(n) == 10 and int(steps) >= 1


def test_the_several_target_environment_block_runs_as_written(tmp_path):
    out = _run(_block("swarm_observation_layout(len(env.possible_agents)"), tmp_path)
    slots, xi = out.split("]", 1)
    assert slots.startswith("[") and len(slots.split(",")) == 4  # swarm-3's four slots
    assert len(xi.strip().strip("[]").split()) == 3  # one Xi per target


def test_the_normalized_environment_block_runs_as_written(tmp_path):
    import numpy as np

    from trackjam.env import swarm_observation_layout, swarm_state_layout

    out = _run(_block("env = normalized(parallel_env("), tmp_path)
    frame, obs, state, metres = re.fullmatch(r"(\(.*?\)) (\(.*?\)) (\(.*?\)) \[(.*)\]\n", out, re.S).groups()
    assert frame == "(240, 320, 3)"
    assert obs == f"({len(swarm_observation_layout(5, 4))},)" and state == f"({len(swarm_state_layout(5, 3))},)"
    own = np.array(metres.split(), dtype=float)  # the agent's position, inside the 100 m area
    assert own.shape == (3,) and np.all((own >= 0) & (own <= 100))


def test_the_docs_swarm_3_table_is_what_the_run_prints(tmp_path):
    """The table docs/several-targets.md shows for `trackjam run swarm-3` (seed 1) is printed by the
    run today, row for row (the rows it leaves out aside)."""
    block = SEVERAL_TARGETS.split("![swarm-3, seed 1](swarm-3.png)", 1)[1].split("```", 2)[1]
    shown = closing_table_rows(block)
    assert len(shown) >= 10 and "label switches per target" in shown
    r = CliRunner().invoke(app, ["run", "swarm-3", "--out", str(tmp_path / "run"), "--no-figures"])
    assert r.exit_code == 0, r.output
    printed = closing_table_rows(r.output)
    assert {k: printed.get(k) for k in shown} == shown


def test_the_readmes_policy_table_rows_are_what_rollout_gives_today():
    """The learning environment's table (10 seeds of paper-fig3): its fast rows, recomputed with
    the README's own rollout code, read as the README prints them (mean ± 95 % interval)."""
    import numpy as np
    from scipy import stats

    import trackjam
    from trackjam.env import parallel_env, random_policy, rollout, solver_policy

    part = README.split("What the policies score", 1)[1].split("\n\n", 2)[1]
    rows, pointing = {}, None
    for line in part.splitlines()[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        pointing = cells[0].split("`")[1] if cells[0] else pointing
        rows[(pointing, cells[1])] = cells[2:5]

    def shown(x):
        x = np.asarray(x, dtype=float)
        half = stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x))
        return f"{x.mean():.1f} ± {half:.1f}"

    for pointing, name in [("aim", "exact"), ("aim", "random"), ("truth", "random")]:
        env = parallel_env(trackjam.load_scenario("paper-fig3", [f"antenna.pointing={pointing}"]), jam_penalty=1.0)
        policy = random_policy(env) if name == "random" else solver_policy(env, name)
        episodes = rollout(env, policy, range(1, 11))
        ret, pen = [e["return"] for e in episodes], [e["penalty"] for e in episodes]
        want_ret, _, want_pen = rows[(pointing, name)]
        assert shown(ret) == want_ret, (pointing, name)
        assert want_pen == "0" if not any(pen) else shown(pen) == want_pen, (pointing, name)


def test_an_experiment_registered_from_a_script_runs_as_written(tmp_path):
    """Extending trackjam: an experiment added to EXPERIMENTS outside the package runs through
    run_experiment and writes its paired comparison."""
    out = _run(_block('EXPERIMENTS["lead"]'), tmp_path)
    label, diff = out.strip().splitlines()[-1].rsplit(" ", 1)
    written = {p.name for p in (tmp_path / "runs" / "experiment-lead").iterdir()}
    assert {"summary.csv", "paired.csv", "lead.png", "trials"} <= written
    import csv

    with open(tmp_path / "runs" / "experiment-lead" / "paired.csv", newline="") as f:
        paired = list(csv.DictReader(f))
    assert label == "lead 0 -> 0.5" == paired[0]["label"]
    # what the script printed (result.paired, in full) is the file's, which keeps 6 significant figures
    assert float(paired[0]["ospa_diff"]) == float(f"{float(diff):.6g}")
