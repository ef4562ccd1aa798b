"""The interactive replay: one frame per step, cones of the right shape, self-contained HTML that
a headless Chromium loads without a JavaScript error and renders."""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess

import matplotlib.image as mpimg
import numpy as np
import pytest
from fake_run import fake_run, fake_scenario
from test_figure import quiet_run

from trackjam.radio.antenna import inside_cone
from trackjam.viz.figure import interference_per_step
from trackjam.viz.replay import (
    MAX_FRAMES,
    TRAIL_FRAMES,
    clip_mesh_to_box,
    cone_mesh,
    replay_figure,
    shown_steps,
    write_replay,
)
from trackjam.simulation.build import antenna_model, figure_settings

ERROR_HOOK = """<script>
function __trackjamReport(msg) {
  var d = document.getElementById('js-errors');
  if (!d) { d = document.createElement('pre'); d.id = 'js-errors';
            (document.body || document.documentElement).appendChild(d); }
  d.textContent += msg + '\\n';
}
window.addEventListener('error', function (e) { __trackjamReport('Uncaught ' + e.message); });
window.addEventListener('unhandledrejection', function (e) { __trackjamReport('Unhandled ' + e.reason); });
</script>"""

# Once the plot and its frames exist, go to the last frame as the slider does, wait until the
# page shows it (the promise of Plotly.animate may wait on animation frames that headless
# Chromium does not always run), then report what the page shows.
PROBE = """<script>
(function () {
  var tries = 0, gd = null, last = null;
  function report() {
    var out = document.createElement('pre');
    out.id = 'replay-probe';
    out.textContent = JSON.stringify({
      frames: gd._transitionData._frames.length, traces: gd.data.length,
      title: gd.layout.title.text,
      webgl: !!(gd._fullLayout.scene._scene && gd._fullLayout.scene._scene.glplot)});
    document.body.appendChild(out);
  }
  var timer = setInterval(function () {
    tries += 1;
    if (tries > 400) { clearInterval(timer); __trackjamReport('probe timed out'); return; }
    if (last === null) {
      gd = document.getElementById('trackjam-replay');
      if (!(gd && gd._fullLayout && gd._transitionData && gd._transitionData._frames.length)) return;
      var frames = gd._transitionData._frames;
      last = frames[frames.length - 1].name;
      Plotly.animate(gd, [last], {frame: {duration: 0, redraw: true}, transition: {duration: 0},
                                  mode: 'immediate'}).catch(function (e) { __trackjamReport('animate: ' + e); });
    } else if (gd.layout.title.text.indexOf('t = ' + last + ' ') === 0) {
      clearInterval(timer);
      report();
    }
  }, 25);
})();
</script>"""

CHROMIUM_FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-quic",
    "--no-first-run", "--disable-background-networking", "--disable-component-update",
    "--disable-sync", "--enable-logging=stderr", "--v=0", "--window-size=1000,800",
    "--virtual-time-budget=5000",
]


CONE = '"type":"mesh3d","x":'  # a cone trace (the template names the type without data)


@pytest.fixture(scope="module")
def run():
    return fake_run()


@pytest.fixture(scope="module")
def replay_html(run, tmp_path_factory):
    steps, agents, scenario = run
    return write_replay(steps, agents, figure_settings(scenario), tmp_path_factory.mktemp("replay") / "replay.html")


def _chromium(chromium, tmp_path, html, *args):
    cmd = [str(chromium), *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}", *args,
           html.resolve().as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def probed_report(chromium, tmp_path, html: str) -> dict:
    """Load the page ``html`` with the error hook and the probe in headless Chromium: no
    JavaScript error, the plot drawn, and what the probe reported (frames, traces, title, ...)."""
    probed = tmp_path / "probed.html"
    probed.write_text(html.replace("<head>", "<head>" + ERROR_HOOK, 1).replace("</body>", PROBE + "</body>", 1))
    proc = _chromium(chromium, tmp_path, probed, "--dump-dom")
    dom = proc.stdout
    assert 'id="js-errors"' not in dom, re.search(r'<pre id="js-errors">(.*?)</pre>', dom, re.S).group(1)
    assert "Uncaught" not in proc.stderr
    assert "plot-container" in dom
    probe = re.search(r'<pre id="replay-probe">(.*?)</pre>', dom, re.S)
    assert probe, "the probe never reported: the plot did not finish drawing"
    return json.loads(probe.group(1).replace("&gt;", ">").replace("&lt;", "<").replace("&amp;", "&"))


def test_cone_mesh_is_the_sensing_cone():
    """Apex at the agent, rim at h_a along the axis with radius h_a tan(theta_a/2) (docs/model.md)."""
    apex, point = np.array([10.0, 20.0, 30.0]), np.array([40.0, 0.0, 50.0])
    h, half = 40.0, np.deg2rad(40)
    v, f = cone_mesh(apex, point, h, half, segments=16)
    axis = (point - apex) / np.linalg.norm(point - apex)
    rim = v[1:-1]
    np.testing.assert_allclose(v[0], apex)
    np.testing.assert_allclose((rim - apex) @ axis, h)
    np.testing.assert_allclose(np.linalg.norm(rim - v[-1], axis=1), h * np.tan(half))
    np.testing.assert_allclose(v[-1], apex + h * axis)
    assert f.shape == (32, 3) and f.min() == 0 and f.max() == len(v) - 1
    # the rim bounds the cone the radio model uses: a little inward is inside, outward is not
    centre = v[-1]
    assert inside_cone(centre + 0.99 * (rim - centre), apex, point, h, half).all()
    assert not inside_cone(centre + 1.01 * (rim - centre), apex, point, h, half).any()


def test_one_frame_per_step_with_title_and_cones(run):
    steps, agents, scenario = run
    fig = replay_figure(steps, agents, figure_settings(scenario))
    T, N = scenario.steps, scenario.n_agents
    assert [f["name"] for f in fig["frames"]] == [str(t) for t in range(1, T + 1)]
    power = agents["power_w"].reshape(T, N)
    for k, frame in enumerate(fig["frames"]):
        assert [tr["name"] for tr in frame["data"]] == [tr["name"] for tr in fig["data"]]
        assert frame["layout"]["title"]["text"].startswith(f"t = {k + 1} ")
        assert "steps shown" not in frame["layout"]["title"]["text"]
        cones = [tr for tr in frame["data"] if tr["type"] == "mesh3d"]
        assert len(cones) == N
        for j, cone in enumerate(cones):
            drawn = np.ptp(np.asarray(cone["x"], dtype=float)) > 0
            assert drawn == (power[k, j] > 0)  # an antenna that is off draws no cone


@pytest.mark.parametrize("max_frames", [None, 3])
def test_jammed_agents_and_jamming_links_follow_the_logs(run, max_frames):
    """Each frame shows its own step's jamming, also when only some steps get a frame."""
    steps, agents, scenario = run
    T, N = scenario.steps, scenario.n_agents
    max_frames = max_frames or T
    fig = replay_figure(steps, agents, figure_settings(scenario), max_frames=max_frames)
    R = interference_per_step(agents, figure_settings(scenario))
    delta = antenna_model(scenario).delta_w
    jammed = agents["jammed"].reshape(T, N)
    x = agents["x"].reshape(T, N)
    assert len(fig["frames"]) == min(T, max_frames)
    for f, frame in enumerate(fig["frames"]):
        k = int(frame["name"]) - 1
        by_name = {tr["name"]: tr for tr in frame["data"]}
        ring = by_name["jammed agent (red ring)"]
        ring_x = np.asarray(ring["x"], dtype=float)
        assert np.allclose(sorted(ring_x[np.isfinite(ring_x)]), sorted(x[k, jammed[k]]), atol=1e-3)
        links = np.asarray(by_name["jams (sender -> receiver)"]["x"], dtype=float)
        assert np.isfinite(links).sum() == 2 * (R[k] >= delta).sum()  # one segment per pair


def test_quiet_run_replays_without_cones_or_target(tmp_path):
    steps, agents, scenario = quiet_run()
    fig = replay_figure(steps, agents, figure_settings(scenario))
    assert len(fig["frames"]) == scenario.steps
    for frame in fig["frames"]:
        for tr in frame["data"]:
            if tr["type"] == "mesh3d":
                assert np.ptp(np.asarray(tr["x"], dtype=float)) == 0
            if tr["name"] in ("target (truth)", "target trail"):
                assert all(v is None for v in tr["x"])
    html = write_replay(steps, agents, figure_settings(scenario), tmp_path / "replay.html").read_text()
    assert html.count(CONE) == scenario.n_agents * (scenario.steps + 1)


def _figure_json(html: str) -> str:
    return html[html.index("Plotly.newPlot"):]


def test_replay_is_self_contained(replay_html, run):
    html = replay_html.read_text()
    assert not re.search(r"<script[^>]*\bsrc\s*=", html)  # plotly.js inlined: no CDN, no file
    head = html[: html.index("Plotly.newPlot")]
    assert "plotly.js" in head and "window.Plotly" in head  # the library itself, before the plot
    figure_json = _figure_json(html)
    _, _, scenario = run
    for t in range(1, scenario.steps + 1):  # one frame per step, named by it
        assert figure_json.count(f'"name":"{t}"') == 1
    assert figure_json.count(CONE) == scenario.n_agents * (scenario.steps + 1)


def test_shown_steps_keep_the_first_and_last_and_spread_evenly():
    assert shown_steps(30).tolist() == list(range(30))
    k = shown_steps(1000)
    assert len(k) == MAX_FRAMES and k[0] == 0 and k[-1] == 999
    gaps = np.diff(k)
    assert gaps.min() >= 999 // (MAX_FRAMES - 1) and gaps.max() <= -(-999 // (MAX_FRAMES - 1))
    assert shown_steps(5, max_frames=3).tolist() == [0, 2, 4]


def test_a_long_run_is_decimated_and_says_so(tmp_path):
    steps, agents, scenario = fake_run(fake_scenario(1000))
    fig = replay_figure(steps, agents, figure_settings(scenario))
    frames = fig["frames"]
    assert len(frames) == MAX_FRAMES
    assert frames[0]["name"] == "1" and frames[-1]["name"] == "1000"
    assert all(f["layout"]["title"]["text"].endswith(f"{MAX_FRAMES} of 1000 steps shown") for f in frames)
    assert f"a frame every {1000 / MAX_FRAMES:.2g} steps" in fig["layout"]["annotations"][0]["text"]
    truth = np.stack([steps[f"truth_{a}"] for a in "xyz"], axis=1)
    for f in (frames[10], frames[-1]):  # the trail ends at the frame's step and is at most TRAIL_FRAMES long
        trail = next(tr for tr in f["data"] if tr["name"] == "target trail")
        assert len(trail["x"]) == min(TRAIL_FRAMES, frames.index(f) + 1)
        k = int(f["name"]) - 1
        if np.isfinite(truth[k, 0]):
            assert trail["x"][-1] == pytest.approx(truth[k, 0], abs=1e-3)
    html = write_replay(steps, agents, figure_settings(scenario), tmp_path / "replay.html").read_text()
    # the page holds MAX_FRAMES frames and no more: its data grows with the frames, not the steps
    assert _figure_json(html).count(CONE) == scenario.n_agents * (MAX_FRAMES + 1)
    short_steps, short_agents, short_scenario = fake_run(fake_scenario(300))
    short = write_replay(short_steps, short_agents, figure_settings(short_scenario), tmp_path / "short.html").read_text()
    assert len(_figure_json(html)) < 1.5 * len(_figure_json(short))


def test_replay_loads_in_chromium_without_errors(chromium_path, replay_html, run, tmp_path):
    steps, _, scenario = run
    report = probed_report(chromium_path, tmp_path, replay_html.read_text())
    assert report["frames"] == scenario.steps
    assert report["title"].startswith(f"t = {scenario.steps} ")
    assert report["webgl"], "the 3D scene has no WebGL context"



def test_replay_renders_a_scene_in_chromium(chromium_path, replay_html, tmp_path):
    shot = tmp_path / "replay.png"
    proc = _chromium(chromium_path, tmp_path, replay_html, f"--screenshot={shot}")
    assert "Uncaught" not in proc.stderr
    img = mpimg.imread(shot)[..., :3]
    assert img.shape[:2] == (800, 1000)
    non_white = (img < 0.95).any(axis=-1).mean()
    colours = len(np.unique((img * 255).astype(np.uint8).reshape(-1, 3), axis=0))
    # saturated pixels come from the cones, trails and markers drawn by WebGL, not from the
    # grey axes and text
    saturation = img.max(axis=-1) - img.min(axis=-1)
    # without WebGL the page is one grey block with a message: ~240 colours, 0.7 % saturated
    assert 0.1 < non_white < 0.9 and colours > 1000, (non_white, colours)
    assert (saturation > 0.1).mean() > 0.02, (saturation > 0.1).mean()


def test_each_frame_names_and_colours_its_steps_track_quality(run):
    # a false track had been drawn in the same colour as a held one, under a title that said only
    # "track" (the planning mode)
    from trackjam.metrics.track_quality import CLASSES, step_classes
    from matplotlib.colors import to_hex

    from trackjam.viz.figure import QUALITY_COLOURS, QUALITY_LABELS

    steps, agents, scenario = run
    fs = figure_settings(scenario)
    names = np.asarray(CLASSES)[step_classes(steps, fs.gate)]
    assert len(set(names)) > 1  # the fake run has more than one class
    fig = replay_figure(steps, agents, fs)
    for k, frame in enumerate(fig["frames"]):
        title = frame["layout"]["title"]["text"]
        assert f"track quality: {QUALITY_LABELS[names[k]]}" in title
        marker = next(tr for tr in frame["data"] if tr["name"].startswith("reported estimate"))
        assert marker["marker"]["color"] == to_hex(QUALITY_COLOURS[names[k]])  # plotly takes no "0.85" grey


def test_the_page_title_names_the_run(tmp_path):
    # the page had no <title>: a browser's tab and bookmarks read "replay.html" for every run
    steps, agents, scenario = fake_run()
    fs = dataclasses.replace(figure_settings(scenario), name="fig3 <b>&</b>")
    html = write_replay(steps, agents, fs, tmp_path / "replay.html").read_text()
    head = html[: html.index("</head>")]
    assert re.findall(r"<title>(.*?)</title>", head) == [
        f"trackjam replay: fig3 &lt;b&gt;&amp;&lt;/b&gt; (solver {fs.solver})"]


def _triangle_areas(v, f):
    t = np.asarray(v, dtype=float)[np.asarray(f)]
    return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)


def test_clip_mesh_to_box_keeps_the_part_inside_and_nothing_else():
    """A cone across two walls is cut there: every vertex inside, the surface kept is the part of
    the cone's surface inside the box (sampled), its apex is kept; a cone inside is untouched, one
    outside is gone."""
    low, high = np.zeros(3), np.array([100.0, 100.0, 50.0])
    apex, point = np.array([5.0, 50.0, 35.0]), np.array([20.0, 60.0, 50.0])
    v, f = cone_mesh(apex, point, 40.0, np.deg2rad(40))
    assert ((v < low) | (v > high)).any()  # the cone reaches past the walls x = 0 and z = 50
    cv, cf = clip_mesh_to_box(v, f, low, high)
    cv = np.asarray(cv)
    assert len(cf) > 0 and cf.max() < len(cv)
    assert ((cv >= low) & (cv <= high)).all()
    assert np.isclose(cv, apex).all(axis=1).any()
    # the surface kept: sample the cone's surface, the share inside times its area
    rng = np.random.default_rng(3)
    areas = _triangle_areas(v, f)
    pick = rng.choice(len(f), size=200_000, p=areas / areas.sum())
    a, b = rng.random((2, len(pick), 1))
    flip = a + b > 1
    a, b = np.where(flip, 1 - a, a), np.where(flip, 1 - b, b)
    t = v[f[pick]]
    sample = t[:, 0] + a * (t[:, 1] - t[:, 0]) + b * (t[:, 2] - t[:, 0])
    share = ((sample >= low) & (sample <= high)).all(axis=1).mean()
    assert 0.05 < share < 0.95, share
    assert _triangle_areas(cv, cf).sum() == pytest.approx(share * areas.sum(), rel=0.01)
    inside_v, inside_f = cone_mesh(np.array([50.0, 50.0, 10.0]), np.array([50.0, 50.0, 40.0]), 20.0, 0.5)
    same_v, same_f = clip_mesh_to_box(inside_v, inside_f, low, high)
    assert same_v is inside_v and same_f is inside_f
    far_v, far_f = clip_mesh_to_box(v + [500.0, 0, 0], f, low, high)
    assert len(far_f) == 0


def test_replay_cones_stay_inside_the_area():
    """With agents near the walls and the corners, no cone vertex of any frame lies outside the
    area (the scene's axes): the cones had been drawn through the walls."""
    s = fake_scenario(8)
    s = s.model_copy(update={"agents": s.agents.model_copy(update={
        "initial": [[1.0, 1.0, 1.0], [99.0, 50.0, 98.0], [50.0, 99.5, 0.5]]})})
    steps, agents, scenario = fake_run(s)
    fs = figure_settings(scenario)
    low, high = fs.low, fs.high
    fig = replay_figure(steps, agents, fs)
    ant = fs.antenna
    T, N = scenario.steps, scenario.n_agents
    u = np.stack([agents[a] for a in "xyz"], axis=1).reshape(T, N, 3)
    point = np.stack([agents[f"point_{a}"] for a in "xyz"], axis=1).reshape(T, N, 3)
    power = agents["power_w"].reshape(T, N)
    reaching_out = cut = 0
    for k, frame in enumerate(fig["frames"]):
        cones = [tr for tr in frame["data"] if tr["type"] == "mesh3d"]
        for j, cone in enumerate(cones):
            xyz = np.array([cone[a] for a in "xyz"], dtype=float).T
            assert np.isfinite(xyz).all()
            assert ((xyz >= low) & (xyz <= high)).all(), (k, j, xyz.min(axis=0), xyz.max(axis=0))
            if power[k, j] > 0:
                full, _ = cone_mesh(u[k, j], point[k, j], ant.height, ant.half_angle)
                if ((full < low) | (full > high)).any():
                    reaching_out += 1
                    cut += len(cone["i"]) != 2 * (len(full) - 2)
                assert np.ptp(xyz, axis=0).max() > 0  # cut, still drawn
    assert reaching_out > 5 and cut == reaching_out  # the test has cones to cut, and they were
