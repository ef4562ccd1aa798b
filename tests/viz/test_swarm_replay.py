"""The replay of a run with several targets: a self-contained page, one trace group per target
and one for the reported tracks (held ones in their target's colour, false ones grey), the team
as the one-target replay draws it with its cones inside the area, the one-target frame limits,
a target that appears late and one that is downed; and a headless Chromium finds the plot."""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.colors import to_hex
from test_replay import probed_report

from swarm_scenarios import two_targets
from trackjam.simulation.build import figure_settings
from trackjam.simulation.loop import simulate
from trackjam.viz.figure import cone_mesh, interference_per_step
from trackjam.viz.replay import MAX_FRAMES, TRAIL_FRAMES, shown_steps
from trackjam.viz.swarm import NONE_COLOUR, target_colours
from trackjam.viz.swarm_replay import TRACKS_NAME, swarm_replay_figure, write_swarm_replay

T = 8
# target a is downed at step 2 (its fail-safe starts at once), b appears at step 4; the agents
# start at the walls and corners, so that cones reach past them
SCENARIO = [
    f"steps={T}", "control.solver=greedy",
    "targets=[{id: a, initial: [20, 20, 20, 1.5, 2.0, 1.7], "
    "response: {threshold_db: -200, steps: 2, action: land, speed: 4}}, "
    "{id: b, initial: [60, 60, 60, -1, 0, 0], appears: 4}]",
    "agents.initial=[[1, 1, 1], [99, 50, 98], [50, 99.5, 0.5]]",
]


@pytest.fixture(scope="module")
def run():
    return simulate(two_targets(*SCENARIO))


@pytest.fixture(scope="module")
def page(run, tmp_path_factory):
    return write_swarm_replay(run.tables, figure_settings(run.scenario),
                              tmp_path_factory.mktemp("swarm-replay") / "replay.html")


def _names(frame):
    return [tr["name"] for tr in frame["data"]]


def stretched(tables: dict, times: int) -> dict:
    """The run's logs repeated ``times`` times one after the other, as one run ``times`` as long."""
    T = len(tables["steps"]["t"])
    out = {}
    for name, cols in tables.items():
        out[name] = {c: np.concatenate([np.asarray(v) + n * T if c == "t" else np.asarray(v) for n in range(times)])
                     for c, v in cols.items()}
    return out


def test_the_page_is_self_contained_and_names_the_run(page, run):
    html = page.read_text()
    assert not re.search(r"<script[^>]*\bsrc\s*=", html)  # no script from a file or the network
    assert not re.search(r"""src\s*=\s*["']?https?:""", html)
    head = html[: html.index("Plotly.newPlot")]
    assert "plotly.js" in head and "window.Plotly" in head
    fs = figure_settings(run.scenario)
    assert re.findall(r"<title>(.*?)</title>", html[: html.index("</head>")]) == [
        f"trackjam replay: {fs.name} (solver {fs.solver})"]
    data = html[html.index("Plotly.newPlot"):]
    for t in range(1, T + 1):
        assert data.count(f'"name":"{t}"') == 1  # one frame per step, named by it


def test_one_trace_group_per_target_and_the_tracks(run):
    fig = swarm_replay_figure(run.tables, figure_settings(run.scenario))
    N = 3
    expected = ["target a trail", "target a", "target b trail", "target b", TRACKS_NAME,
                *(f"trail {j}" for j in (1, 2, 3)), *(f"agent {j}" for j in (1, 2, 3)),
                *(f"cone {j}" for j in (1, 2, 3)), "jammed agent (red ring)", "jams (sender -> receiver)"]
    colours = [to_hex(c) for c in target_colours(2)]
    assert colours[0] != colours[1]
    tr = run.tables["tracks"]
    false_seen = held_seen = 0
    for frame in fig["frames"]:
        assert _names(frame) == expected  # the same traces in every frame (plotly updates by index)
        by = {t["name"]: t for t in frame["data"]}
        for k, name in enumerate("ab"):
            assert by[f"target {name} trail"]["legendgroup"] == by[f"target {name}"]["legendgroup"] == f"target{k}"
            assert by[f"target {name} trail"]["line"]["color"] == by[f"target {name}"]["marker"]["color"] == colours[k]
            assert by[f"target {name}"]["marker"]["line"]["color"] == "black"  # apart from an agent of that colour
        t = int(frame["name"])
        rows = tr["t"] == t
        tracks = by[TRACKS_NAME]
        if not rows.any():
            assert tracks["x"] == [None]
            continue
        assert tracks["text"] == list(tr["track"][rows])  # each track labelled
        np.testing.assert_allclose(np.asarray(tracks["x"], dtype=float), tr["est_x"][rows], atol=1e-3)
        want = [colours["ab".index(g)] if g else NONE_COLOUR for g in tr["target"][rows]]
        assert tracks["marker"]["color"] == want
        false_seen += want.count(NONE_COLOUR)
        held_seen += len(want) - want.count(NONE_COLOUR)
    assert false_seen > 0 and held_seen > 0  # the run has both kinds of track


def test_a_late_target_is_absent_until_it_appears_and_a_downed_one_says_so(run):
    fig = swarm_replay_figure(run.tables, figure_settings(run.scenario))
    tg = run.tables["targets"]
    exists = tg["exists"].reshape(T, 2)
    downed = tg["downed"].reshape(T, 2)
    assert not exists[:3, 1].any() and exists[3:, 1].all()  # b appears at step 4
    assert not downed[0, 0] and downed[1:, 0].all()  # a is downed from step 2
    for k, frame in enumerate(fig["frames"]):
        by = {t["name"]: t for t in frame["data"]}
        b = by["target b"]
        if k < 3:
            assert b["x"] == [None] and all(v is None for v in by["target b trail"]["x"])
        else:
            assert b["x"][0] == pytest.approx(tg["truth_x"][2 * k + 1], abs=1e-3)
            assert b["marker"]["symbol"] == "diamond" and "flying" in b["hovertext"][0]
        a = by["target a"]
        assert a["marker"]["symbol"] == ("x" if downed[k, 0] else "diamond")
        assert ("downed" in a["hovertext"][0]) == downed[k, 0] and ("(downed)" in a["text"][0]) == downed[k, 0]
        assert a["x"][0] == pytest.approx(tg["truth_x"][2 * k], abs=1e-3)
    # the title counts what the step holds
    steps = run.tables["steps"]
    for k, frame in enumerate(fig["frames"]):
        title = frame["layout"]["title"]["text"]
        assert title.startswith(f"t = {k + 1}   |   targets present {steps['targets_present'][k]}, ")
        assert f"tracks reported {steps['tracks'][k]} " in title and f"planning: {steps['mode'][k]}" in title


def test_cones_point_where_the_antennas_pointed_and_stay_inside_the_area(run):
    fs = figure_settings(run.scenario)
    fig = swarm_replay_figure(run.tables, fs)
    ag = run.tables["agents"]
    N = 3
    u = np.stack([ag[a] for a in "xyz"], axis=1).reshape(T, N, 3)
    point = np.stack([ag[f"point_{a}"] for a in "xyz"], axis=1).reshape(T, N, 3)
    power = ag["power_w"].reshape(T, N)
    ant = fs.antenna
    reaching_out = drawn = 0
    for k, frame in enumerate(fig["frames"]):
        cones = [tr for tr in frame["data"] if tr["type"] == "mesh3d"]
        assert [c["name"] for c in cones] == ["cone 1", "cone 2", "cone 3"]
        for j, cone in enumerate(cones):
            xyz = np.array([cone[a] for a in "xyz"], dtype=float).T
            assert np.isfinite(xyz).all()
            assert ((xyz >= fs.low) & (xyz <= fs.high)).all(), (k, j)
            if power[k, j] > 0:
                drawn += 1
                full, _ = cone_mesh(u[k, j], point[k, j], ant.height, ant.half_angle)
                inside = ((full >= fs.low) & (full <= fs.high)).all(axis=1)
                reaching_out += not inside.all()
                # the drawn vertices are the full cone's inside the area, plus the cuts: the
                # apex is the agent and the rim centre, when inside, is on the aim's axis
                assert np.isclose(xyz, u[k, j], atol=2e-3).all(axis=1).any()
                if inside[-1]:
                    assert np.isclose(xyz, full[-1], atol=2e-3).all(axis=1).any()
            else:
                assert np.ptp(xyz, axis=0).max() == 0  # an antenna that is off draws no cone
    assert drawn > 5 and reaching_out > 0  # the test has cones, and some to cut


def test_jammed_agents_and_jamming_links_follow_the_logs(run):
    fs = figure_settings(run.scenario)
    fig = swarm_replay_figure(run.tables, fs, max_frames=3)
    ag = run.tables["agents"]
    jammed = ag["jammed"].reshape(T, 3)
    x = ag["x"].reshape(T, 3)
    R = interference_per_step(ag, fs)
    assert [f["name"] for f in fig["frames"]] == [str(k + 1) for k in shown_steps(T, 3)]
    for frame in fig["frames"]:
        k = int(frame["name"]) - 1
        by = {t["name"]: t for t in frame["data"]}
        ring = np.asarray(by["jammed agent (red ring)"]["x"], dtype=float)
        assert np.allclose(sorted(ring[np.isfinite(ring)]), sorted(x[k, jammed[k]]), atol=1e-3)
        links = np.asarray(by["jams (sender -> receiver)"]["x"], dtype=float)
        assert np.isfinite(links).sum() == 2 * (R[k] >= fs.antenna.delta_w).sum()


def test_a_long_run_keeps_the_one_target_frame_limits(run):
    times = -(-(MAX_FRAMES + 50) // T)  # longer than MAX_FRAMES steps
    long = stretched(run.tables, times)
    fig = swarm_replay_figure(long, figure_settings(run.scenario))
    frames = fig["frames"]
    total = T * times
    assert len(frames) == MAX_FRAMES
    assert [f["name"] for f in frames] == [str(k + 1) for k in shown_steps(total)]
    assert all(f["layout"]["title"]["text"].endswith(f"{MAX_FRAMES} of {total} steps shown") for f in frames)
    assert len(fig["layout"]["sliders"][0]["steps"]) == MAX_FRAMES
    for f in (frames[5], frames[-1]):
        trail = next(tr for tr in f["data"] if tr["name"] == "target a trail")
        assert len(trail["x"]) == min(TRAIL_FRAMES, frames.index(f) + 1)
    short = swarm_replay_figure(run.tables, figure_settings(run.scenario))
    assert len(short["frames"]) == T and "steps shown" not in short["frames"][-1]["layout"]["title"]["text"]


def test_a_target_id_is_shown_as_text_not_markup(run, tmp_path):
    tables = {name: dict(cols) for name, cols in run.tables.items()}
    for name in ("targets", "tracks"):
        tables[name]["target"] = np.where(tables[name]["target"] == "b", "<b>x</b>", tables[name]["target"])
    html = write_swarm_replay(tables, figure_settings(run.scenario), tmp_path / "r.html").read_text()
    assert "<b>" not in html.replace("\\u002f", "/")
    assert html.count('"name":"target &lt;b&gt;x&lt;\\u002fb&gt;"') == T + 1  # plotly's JSON writes / as \u002f


def test_the_page_loads_in_chromium_and_shows_the_plot(chromium_path, page, tmp_path):
    report = probed_report(chromium_path, tmp_path, page.read_text())
    assert report["frames"] == T and report["traces"] == 16
    assert report["title"].startswith(f"t = {T} ")
    assert report["webgl"], "the 3D scene has no WebGL context"
