"""The run figure (the paper's Fig. 3 (a)-(h)) and the log helpers it shares with the replay."""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from fake_run import AGENT_COLUMNS, STEP_COLUMNS, fake_run
from matplotlib.figure import Figure

from trackjam.config import load_scenario
from trackjam.viz.figure import (
    _panel_cones,
    _panel_existence,
    _panel_jamming,
    _panel_powers,
    _panel_trajectories,
    agent_positions,
    agent_table,
    interference_per_step,
    jamming_events,
    level_labels,
    occluded_steps,
    path_box,
    plot_run,
    snapshot_steps,
    to_db,
)
from trackjam.viz.replay import replay_figure
from trackjam.simulation.build import antenna_model, figure_settings


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


class _Reads(dict):
    """A log that remembers which columns were read."""

    def __init__(self, columns):
        super().__init__(columns)
        self.read: set[str] = set()

    def __getitem__(self, key):
        self.read.add(key)
        return super().__getitem__(key)

    def __contains__(self, key):
        self.read.add(key)
        return super().__contains__(key)


@pytest.fixture(scope="module")
def real_run():
    """A real run of the simulation, as short and cheap as it gets, with an occlusion."""
    from trackjam.simulation.loop import simulate

    s = load_scenario("paper-fig3", ["steps=4", "filter.particles=300", "filter.birth_particles=60",
                                     "control.grasp.samples=50", "control.grasp.iterations=2", "target.occlusions=[[2, 2]]"])
    r = simulate(s)
    return r.steps, r.agents, s


def test_the_figures_read_only_columns_a_real_run_logs_and_the_fake_run_copies_them(real_run, tmp_path):
    steps, agents, scenario = real_run
    steps, agents = _Reads(steps), _Reads(agents)
    plot_run(steps, agents, figure_settings(scenario), tmp_path / "run.png")
    replay_figure(steps, agents, figure_settings(scenario))
    assert steps.read - {"mode"} <= set(STEP_COLUMNS) <= set(steps)
    assert agents.read <= set(AGENT_COLUMNS) <= set(agents)
    from trackjam.viz.figure import READ_AGENTS, READ_STEPS  # what run_shape asks of the logs

    assert set(READ_STEPS) == set(STEP_COLUMNS) and set(READ_AGENTS) == set(AGENT_COLUMNS)
    fake_steps, fake_agents, _ = fake_run()
    for real, fake in ((steps, fake_steps), (agents, fake_agents)):
        for col in fake:  # same kind of values: bool, integer or float
            assert np.asarray(fake[col]).dtype.kind == np.asarray(dict.__getitem__(real, col)).dtype.kind, col


def test_a_real_run_draws(real_run, tmp_path):
    steps, agents, scenario = real_run
    _assert_png_drawn(plot_run(steps, agents, figure_settings(scenario), tmp_path / "run.png"))


def test_panel_a_zooms_to_the_paths_inside_the_area(run):
    steps, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    ax = Figure().add_subplot(projection="3d")
    _panel_trajectories(ax, steps, agents, figure_settings(scenario), T, N)
    u = np.stack([agents[c] for c in "xyz"], axis=1)
    lo, hi = np.array([ax.get_xlim(), ax.get_ylim(), ax.get_zlim()]).T
    assert np.all(lo >= 0) and np.all(hi <= 100)
    assert np.all(u >= lo) and np.all(u <= hi)
    assert (hi - lo).max() < 60  # the paths span ~25 m, not the 100 m box


def test_path_box():
    fs = figure_settings(load_scenario("paper-fig3"))
    lo, hi = path_box(np.array([[10.0, 20.0, 30.0], [30.0, 25.0, 31.0], [np.nan] * 3]), fs)
    np.testing.assert_allclose(lo, [8.0, 18.0, 28.0])  # margin: max(10 % of 20 m, 2 m)
    np.testing.assert_allclose(hi, [32.0, 27.0, 33.0])
    lo, hi = path_box(np.array([[1.0, 50.0, 99.0]]), fs)
    np.testing.assert_allclose(lo, [0.0, 48.0, 97.0])  # clipped to the area
    np.testing.assert_allclose(hi, [3.0, 52.0, 100.0])
    lo, hi = path_box(np.full((2, 3), np.nan), fs)
    np.testing.assert_allclose(hi - lo, [100.0] * 3)  # nothing to show: the area


def test_panel_d_leaves_a_gap_where_the_target_gets_no_power(run):
    steps, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    steps = dict(steps)
    w = np.asarray(steps["target_received_w"], dtype=float).copy()
    w[1] = 0.0
    steps["target_received_w"] = w
    ax = Figure().add_subplot()
    _panel_powers(ax, steps, agents, figure_settings(scenario), np.arange(1.0, T + 1), T, N)
    line = ax.lines[0].get_ydata()
    assert np.isnan(line[w == 0]).all() and np.isfinite(line[w > 0]).all()
    np.testing.assert_allclose(line[w > 0], 10 * np.log10(w[w > 0]))
    floor = ax.get_yticks()[0]
    assert ax.get_yticklabels()[0].get_text() == "0 W" and (line[w > 0] > floor).all()
    marks = [c for c in ax.collections if c.get_label() == "no power at the target"]
    assert len(marks) == 1 and marks[0].get_offsets()[:, 0].tolist() == (np.flatnonzero(w == 0) + 1.0).tolist()
    assert 2.0 in marks[0].get_offsets()[:, 0]


def test_recomputed_interference_matches_the_logged_total_and_jamming(run):
    """The pairwise matrix of Eq. (13) sums, per receiver, to what the loop logged."""
    steps, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    R = interference_per_step(agents, figure_settings(scenario))
    assert R.shape == (T, N, N)
    assert np.all(R[:, np.arange(N), np.arange(N)] == 0)
    np.testing.assert_allclose(R.sum(axis=2), agent_table(agents, "interference_w", T, N), rtol=1e-12)
    delta = antenna_model(scenario).delta_w
    assert np.array_equal(R.sum(axis=2) >= delta, agent_table(agents, "jammed", T, N) > 0.5)
    # an antenna that is off sends nothing
    off = agent_table(agents, "power_w", T, N) == 0
    assert np.all(R.transpose(0, 2, 1)[off] == 0)


def test_interference_at_chosen_steps_is_those_rows_of_every_steps(run):
    steps, agents, scenario = run
    fs = figure_settings(scenario)
    R = interference_per_step(agents, fs)
    at = np.array([scenario.steps - 1, 0, 2, 2])
    np.testing.assert_array_equal(interference_per_step(agents, fs, at), R[at])
    assert interference_per_step(agents, fs, np.array([], int)).shape == (0, scenario.n_agents, scenario.n_agents)


@pytest.mark.parametrize("chunk", [1, 2, 3, 1024])
def test_jamming_events_taken_in_chunks_are_those_of_the_whole_array(run, chunk):
    """The figure's panel (c) never holds the (T, N, N) array: its events, found a chunk of steps
    at a time, are those found on the whole array."""
    steps, agents, scenario = run
    fs = figure_settings(scenario)
    R = interference_per_step(agents, fs)
    delta = fs.antenna.delta_w
    k, i, j = np.nonzero(R >= delta)
    only = (R.sum(axis=2) >= delta) & ~(R >= delta).any(axis=2)
    ko, io = np.nonzero(only)
    (pt, pi, pj), (ot, oi) = jamming_events(agents, fs, chunk=chunk)
    assert len(k) > 0  # the fake run has pairs that jam
    assert sorted(zip(pt.tolist(), pi.tolist(), pj.tolist())) == sorted(zip((k + 1).tolist(), i.tolist(), j.tolist()))
    assert sorted(zip(ot.tolist(), oi.tolist())) == sorted(zip((ko + 1).tolist(), io.tolist()))


def test_panel_c_marks_each_pair_that_jams_at_its_steps(run):
    steps, agents, scenario = run
    fs = figure_settings(scenario)
    T, N = scenario.steps, scenario.n_agents
    R = interference_per_step(agents, fs)
    ax = Figure().add_subplot()
    _panel_jamming(ax, agents, fs, T, N)
    marks = [c for c in ax.collections if c.get_offsets().shape[0] > 0]
    drawn = sorted(float(x) for c in marks for x in c.get_offsets()[:, 0])
    pairs = np.nonzero(R >= fs.antenna.delta_w)[0] + 1
    only = np.nonzero((R.sum(axis=2) >= fs.antenna.delta_w) & ~(R >= fs.antenna.delta_w).any(axis=2))[0] + 1
    assert drawn == sorted(float(t) for t in np.concatenate([pairs, only])) and drawn


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
    assert level_labels(figure_settings(scenario)) == ["off", "-50 dBW", "-7 dBW", "0.5 dBW"]
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
    out = plot_run(steps, agents, figure_settings(scenario), tmp_path / "run.png")
    assert out == tmp_path / "run.png" and out.stat().st_size > 50_000
    _assert_png_drawn(out)


def test_plot_run_with_everything_off_and_no_target(tmp_path):
    steps, agents, scenario = quiet_run()
    _assert_png_drawn(plot_run(steps, agents, figure_settings(scenario), tmp_path / "run.png"))


def test_snapshot_steps_pick_the_most_interference_and_the_last_step(run):
    """(g) is the step at which some agent receives the most interference, the earliest of ties,
    as a brute-force scan of the log finds it; (h) the last step."""
    steps, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    fs = figure_settings(scenario)
    (k_g, why_g), (k_h, why_h) = snapshot_steps(agents, fs, T, N)
    rows = sorted(zip(agents["t"], agents["agent"], agents["interference_w"]), key=lambda r: (-r[2], r[0]))
    t_best, j_best, w_best = rows[0]
    assert w_best > 0 and k_g == t_best and f"agent {j_best + 1}" in why_g
    assert f"{10 * np.log10(w_best):.1f} dBW" in why_g
    assert (k_h, why_h.splitlines()[0]) == (T, "the last step")
    # a tie goes to the earlier step
    tied = dict(agents)
    tied["interference_w"] = np.where(np.asarray(agents["t"]) == T, w_best, agents["interference_w"])
    assert snapshot_steps(tied, fs, T, N)[0][0] == t_best


def test_snapshot_steps_without_interference_show_the_middle_step(tmp_path):
    steps, agents, scenario = quiet_run()
    T = scenario.steps
    (k_g, why_g), _ = snapshot_steps(agents, figure_settings(scenario), T, scenario.n_agents)
    assert k_g == (T + 1) // 2 and "no agent receives interference" in why_g


def test_panels_g_h_draw_one_cone_per_transmitting_agent_with_the_cones_geometry(run):
    """The cone drawn for agent j is the sensing cone of the log: its rim at h_a along the axis
    from u_t^j to its aim point, with radius h_a tan(theta_a / 2); an agent that is off draws none."""
    from mpl_toolkits.mplot3d.art3d import Line3D, Poly3DCollection

    steps, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    fs = figure_settings(scenario)
    h, half = fs.antenna.height, fs.antenna.half_angle
    on = agent_table(agents, "power_w", T, N) > 0
    assert on.any() and not on.all()  # the fake run has both, so both cases are drawn
    u_all, point_all = agent_positions(agents, T, N), agent_positions(agents, T, N, "point_")
    for k in range(1, T + 1):
        ax = Figure().add_subplot(projection="3d")
        _panel_cones(ax, steps, agents, fs, T, N, k, "(g) test")
        assert sum(isinstance(c, Poly3DCollection) for c in ax.collections) == on[k - 1].sum()
        rims = [np.column_stack(line.get_data_3d()) for line in ax.lines
                if isinstance(line, Line3D) and len(line.get_data_3d()[0]) > 2]
        assert len(rims) == on[k - 1].sum()
        for rim, j in zip(rims, np.flatnonzero(on[k - 1])):
            u, point = u_all[k - 1, j], point_all[k - 1, j]
            axis = (point - u) / np.linalg.norm(point - u)
            along = (rim - u) @ axis
            radial = np.linalg.norm((rim - u) - along[:, None] * axis, axis=1)
            assert np.allclose(along, h) and np.allclose(radial, h * np.tan(half))


def _odd(kind):
    steps, agents, scenario = fake_run()
    steps, agents, fs = dict(steps), dict(agents), figure_settings(scenario)
    if kind == "empty":
        steps = {k: np.asarray(v)[:0] for k, v in steps.items()}
    elif kind == "missing":
        del steps["ospa"]
    elif kind == "one step of agents":
        agents = {k: np.asarray(v)[np.asarray(agents["t"]) == 1] for k, v in agents.items()}
    elif kind == "unordered":
        steps = {k: np.asarray(v)[::-1] for k, v in steps.items()}
    elif kind == "level 99":
        agents["level_index"] = np.full(len(agents["t"]), 99)
    elif kind == "ragged":
        steps["ospa"] = np.asarray(steps["ospa"])[:-1]
    return steps, agents, fs


@pytest.mark.parametrize("kind, words", [
    ("empty", "steps: t must run 1, 2, ... with one row per step"),  # numpy's "zero-size array" before
    ("missing", "steps: not a run's steps log: missing ospa"),  # KeyError: 'ospa'
    ("one step of agents", "agents: expected one row per step"),  # a 3-step run drawn with one step of agents
    ("unordered", "steps: t must run 1, 2, ..."),
    ("level 99", "agents: level_index must lie in 0..3"),  # the replay's IndexError
    ("ragged", "steps: its columns must be one-dimensional and of one length"),
])
def test_the_figure_and_the_replay_refuse_logs_that_are_not_one_runs(tmp_path, kind, words):
    from trackjam.viz.replay import write_replay

    steps, agents, fs = _odd(kind)
    for draw in (plot_run, write_replay):
        with pytest.raises(ValueError) as err:
            draw(steps, agents, fs, tmp_path / "x")
        assert str(err.value).startswith(words), str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_the_figure_names_settings_that_are_not_a_runs():
    steps, agents, _ = fake_run()
    with pytest.raises(TypeError, match="^fs: expected the run's FigureSettings"):
        plot_run(steps, agents, None, "x.png")


@given(st.sets(st.integers(1, 60)))
def test_the_shaded_spans_are_the_runs_of_consecutive_steps(ks):
    # one span per step had made a 100,000-step figure take minutes and gigabytes
    from trackjam.viz.figure import _spans

    spans = _spans(sorted(ks))
    covered = [k for first, last in spans for k in range(first, last + 1)]
    assert covered == sorted(ks)  # every step once, in order
    assert all(b[0] > a[1] + 1 for a, b in zip(spans, spans[1:]))  # runs apart: no two could merge


def test_panel_e_rings_the_reported_steps_not_every_step_above_one_half(run):
    # its 0.5 line had been labelled "target reported", though under filter.visibility or
    # fusion.report_spread steps above 0.5 go unreported
    steps, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    steps = dict(steps)
    steps["existence"] = np.full(T, 0.7)
    est = np.asarray(steps["est_x"], dtype=float).copy()
    est[::2] = np.nan  # every other step unreported
    steps["est_x"] = est
    ax = Figure().add_subplot()
    _panel_existence(ax, steps, agents, np.arange(1.0, T + 1), T, N)
    ringed = next(line for line in ax.lines if line.get_label() == "reported")
    assert ringed.get_xdata().tolist() == (np.flatnonzero(np.isfinite(est)) + 1.0).tolist()
    assert "target reported" not in [line.get_label() for line in ax.lines]
