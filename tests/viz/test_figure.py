"""The run figure (the paper's Fig. 3 (a)-(f)) and the log helpers it shares with the replay."""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pytest
from fake_run import AGENT_COLUMNS, STEP_COLUMNS, fake_run

from trackjam.radio.antenna import AntennaModel
from trackjam.viz.figure import (
    agent_table,
    interference_per_step,
    level_labels,
    occluded_steps,
    plot_run,
    to_db,
)


@pytest.fixture(scope="module")
def run():
    return fake_run()


def quiet_run():
    """Every antenna off and no target ever: nothing to jam, nothing to track."""
    steps, agents, scenario = fake_run()
    steps, agents = dict(steps), dict(agents)
    n, m = len(steps["t"]), len(agents["t"])
    for c in ("truth_x", "truth_y", "truth_z", "est_x", "est_y", "est_z", "aim_x", "aim_y", "aim_z", "objective"):
        steps[c] = np.full(n, np.nan)
    steps["target_exists"] = steps["target_detectable"] = np.zeros(n, bool)
    steps["existence"] = np.full(n, 0.05)
    steps["ospa"] = np.zeros(n)
    steps["target_received_w"] = np.zeros(n)
    for c in ("power_w", "p_d", "interference_w", "to_target_w"):
        agents[c] = np.zeros(m)
    agents["level_index"] = np.zeros(m, int)
    agents["jammed"] = agents["detected"] = np.zeros(m, bool)
    for c in ("point_x", "point_y", "point_z"):
        agents[c] = np.full(m, np.nan)
    return steps, agents, scenario


def test_fake_run_has_every_log_column(run):
    steps, agents, scenario = run
    assert sorted(steps) == sorted(STEP_COLUMNS)
    assert sorted(agents) == sorted(AGENT_COLUMNS)
    assert len(agents["t"]) == scenario.steps * scenario.n_agents


def test_recomputed_interference_matches_the_logged_total_and_jamming(run):
    """The pairwise matrix of Eq. (13) sums, per receiver, to what the loop logged."""
    steps, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    R = interference_per_step(agents, scenario)
    assert R.shape == (T, N, N)
    assert np.all(R[:, np.arange(N), np.arange(N)] == 0)
    np.testing.assert_allclose(R.sum(axis=2), agent_table(agents, "interference_w", T, N), rtol=1e-12)
    delta = AntennaModel.from_scenario(scenario).delta_w
    assert np.array_equal(R.sum(axis=2) >= delta, agent_table(agents, "jammed", T, N) > 0.5)
    # an antenna that is off sends nothing
    off = agent_table(agents, "power_w", T, N) == 0
    assert np.all(R.transpose(0, 2, 1)[off] == 0)


def test_fake_run_exercises_jamming_and_occlusion(run):
    steps, agents, _ = run
    assert agents["jammed"].any() and not agents["jammed"].all()
    assert list(occluded_steps(steps)) == [3]


def test_agent_table_does_not_depend_on_row_order(run):
    _, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    perm = np.random.default_rng(0).permutation(len(agents["t"]))
    shuffled = {k: v[perm] for k, v in agents.items()}
    for col in ("x", "level_index", "interference_w"):
        np.testing.assert_array_equal(agent_table(shuffled, col, T, N), agent_table(agents, col, T, N))
    assert agent_table(agents, "agent", T, N)[2].tolist() == list(range(N))


def test_level_labels_and_decibels(run):
    scenario = run[2]
    assert level_labels(scenario) == ["off", "-50 dBW", "-7 dBW", "0.5 dBW"]
    db = to_db(np.array([1e-4, 1.0, 0.0]))
    assert db[0] == pytest.approx(-40) and db[1] == 0 and np.isneginf(db[2])


def _assert_png_drawn(path, min_w=1200, min_h=800):
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(path)
    h, w = img.shape[:2]
    assert min_w <= w <= 4000 and min_h <= h <= 3000
    ink = (img[..., :3] < 0.9).any(axis=-1).mean()
    assert 0.03 < ink < 0.6  # drawn on, not a solid block


def test_plot_run_writes_the_figure(run, tmp_path):
    steps, agents, scenario = run
    out = plot_run(steps, agents, scenario, tmp_path / "run.png")
    assert out == tmp_path / "run.png" and out.stat().st_size > 50_000
    _assert_png_drawn(out)


def test_plot_run_with_everything_off_and_no_target(tmp_path):
    steps, agents, scenario = quiet_run()
    _assert_png_drawn(plot_run(steps, agents, scenario, tmp_path / "run.png"))
