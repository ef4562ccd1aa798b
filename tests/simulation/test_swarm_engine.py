"""The swarm engine (several targets): a thin loop over the blocks whose logs agree with the
metrics recomputed from them, one seed giving one run, and the options it does not simulate
refused in one line."""

import re

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.estimation.bernoulli import weighted_moments
from trackjam.estimation.fusion import FusedEstimate
from trackjam.estimation.lmb import LMBFilter
from trackjam.estimation.lmb_fusion import FusedTrack
from trackjam.metrics.ceiling import team_ceiling
from trackjam.metrics.multi import multi_track_quality, ospa_parts
from trackjam.simulation.build import build_swarm, lmb_params
from trackjam.simulation.loop import simulate
from trackjam.simulation.swarm import SwarmSimulation, confirmed, cue_tracks, track_label
from trackjam.simulation.swarm_logs import truth_and_estimates
from trackjam.simulation.swarm_schema import SWARM_TABLES
from trackjam.viz.swarm import served_targets

from readme_tables import SEVERAL_TARGETS, first_column_names
from swarm_scenarios import two_targets




def two(*extra, solver="greedy"):
    return two_targets("steps=5", f"control.solver={solver}", *extra)


@pytest.fixture(scope="module")
def run():
    return simulate(two(solver="exact"))


def test_a_run_writes_every_declared_column_with_one_row_per_step_target_and_agent(run):
    T, K, N = 5, 2, 3
    for name, schema in SWARM_TABLES.items():
        cols = run.tables[name]
        assert list(cols) == [c.name for c in schema]
        for c in schema:
            assert np.asarray(cols[c.name]).dtype.kind == np.dtype(c.dtype).kind, (name, c.name)
    assert len(run.steps["t"]) == T and len(run.tables["targets"]["t"]) == T * K and len(run.agents["t"]) == T * N
    assert list(run.tables["targets"]["target"][:2]) == ["a", "b"]
    assert np.array_equal(run.steps["tracks"], np.bincount(run.tables["tracks"]["t"], minlength=T + 1)[1:])


def test_the_summary_is_the_multi_target_metrics_of_the_logs(run):
    m = run.summary
    truth, est = truth_and_estimates(run.tables, ["a", "b"])
    q = multi_track_quality(truth, est, 5.0, ["a", "b"])
    assert {k: m[k] for k in q} == q
    held = run.tables["targets"]["held"].reshape(5, 2)
    assert m["held_steps"] == [int(v) for v in held.sum(axis=0)]
    for t, x, (_, pos) in zip(run.steps["t"], truth, est):
        o = ospa_parts(x[np.isfinite(x).all(axis=1)], pos)
        np.testing.assert_allclose([run.steps[k][t - 1] for k in ("ospa", "ospa_loc", "ospa_card")], o)
    assert m["ospa_mean"] == pytest.approx(np.mean(run.steps["ospa"]))
    assert m["jamming_incidents"] == [int(v) for v in run.agents["jammed"].reshape(5, 3).sum(axis=0)]
    # the cue puts a confirmed track on each target at the start: both are held at step 1
    assert held[0].all()
    # the team's ceiling on the run's own truth and start
    tg, b = run.tables["targets"], build_swarm(two(solver="exact")).base
    present = np.stack([tg[f"truth_{a}"] for a in "xyz"], axis=1).reshape(5, 2, 3)
    c = team_ceiling(present, tg["detectable"].reshape(5, 2), b.initial_positions, b.max_step, b.low, b.high)
    assert m["ceiling_share"] == c.shares and m["ceiling_share_total"] == c.total and m["ceiling_d_m"] == 8.0
    assert len(m["ceiling_share"]) == 2 and all(0 <= v <= 1 for v in m["ceiling_share"])


def test_a_track_holds_the_target_whose_row_names_it(run):
    tg, tr = run.tables["targets"], run.tables["tracks"]
    for t, target, track in zip(tg["t"], tg["target"], tg["track"]):
        if track:
            assert tr["target"][(tr["t"] == t) & (tr["track"] == track)].tolist() == [target]


def test_one_seed_gives_one_run_and_reset_starts_over():
    s = two()
    a = simulate(s)
    sim = SwarmSimulation(s)
    for _ in range(2):
        sim.step()
    sim.reset()
    while not sim.done:
        sim.step()
    b = sim.result()
    for name in SWARM_TABLES:
        for k, v in a.tables[name].items():
            if k not in ("solve_s", "step_s"):
                np.testing.assert_array_equal(v, b.tables[name][k], err_msg=f"{name}.{k}")
    c = simulate(two("seed=2"))
    assert not np.array_equal(a.tables["targets"]["truth_x"], c.tables["targets"]["truth_x"])


def test_antennas_point_at_the_served_aim_or_under_truth_at_the_matched_target():
    aim = SwarmSimulation(two())
    r = aim.step()
    pts = np.stack([r.agents["point"][:, i] for i in range(3)], axis=1)
    np.testing.assert_array_equal(pts, np.array([a.aim for a in aim.agents]))
    truth = SwarmSimulation(two("antenna.pointing=truth"))
    r = truth.step()
    X = truth.truth.positions
    for j, p in enumerate(r.agents["point"]):
        if r.agents["serves"][j]:
            assert min(np.linalg.norm(X - p, axis=1)) == 0.0 or np.array_equal(p, truth.agents[j].aim)
    # truth pointing puts the cones on the targets: every serving agent points exactly at one
    served = [p for j, p in enumerate(r.agents["point"]) if r.agents["serves"][j]]
    assert served and all(min(np.linalg.norm(X - p, axis=1)) == 0.0 for p in served)


def test_hover_without_a_confirmed_track_keeps_the_aims_and_takes_the_fallback_levels():
    from trackjam.control.fallback import fallback_levels

    sim = SwarmSimulation(two("filter.cue=null"))
    aims = np.array([a.aim for a in sim.agents])
    u = sim.positions
    r = sim.step()
    assert r.step["mode"] == "hover" and list(r.agents["serves"]) == ["", "", ""]
    np.testing.assert_array_equal(r.agents["pos"], u)
    np.testing.assert_array_equal(np.array([a.aim for a in sim.agents]), aims)
    np.testing.assert_array_equal(r.agents["level_index"], fallback_levels(u, aims, sim.c.base.antenna, True))


def test_cue_tracks_sit_at_each_present_targets_first_position():
    s = two("filter.particles=4000")
    lmb = LMBFilter(lmb_params(s), build_swarm(s).base.antenna, np.random.default_rng(0))
    first = np.array([[20.0, 20, 20], [60, 60, 60], [np.nan] * 3])
    tracks = cue_tracks(lmb, first, [True, False, True], (0.9, 2.0, 2.0))
    assert [t.label for t in tracks] == [(0, 0)] and tracks[0].r == 0.9
    mean, cov = weighted_moments(tracks[0].X, np.exp(tracks[0].log_w))
    np.testing.assert_allclose(mean, [20, 20, 20, 0, 0, 0], atol=0.2)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), 2.0, rtol=0.06)


def _fused(members, e):
    return FusedTrack(members, FusedEstimate(e, np.zeros(6), np.eye(6), np.zeros(0)))


def test_a_team_track_is_labelled_by_its_oldest_member_and_the_confirmed_come_most_likely_first():
    f = _fused(((2, (3, 0)), (0, (5, 1)), (1, (3, 1))), 0.7)
    assert track_label(f) == "a1:3.1"  # born first; ties to the lower agent
    g = _fused(((0, (1, 0)),), 0.9)
    h = _fused(((1, (1, 0)),), 0.4)
    assert [track_label(x) for x in confirmed([f, h, g])] == ["a0:1.0", "a1:3.1"]


def test_served_targets_reads_which_agent_serves_which_target(run):
    serve = served_targets(run.tables, ["a", "b"])
    ag, tr = run.agents, run.tables["tracks"]
    for t, j, lab in zip(ag["t"], ag["agent"], ag["serves"]):
        held = tr["target"][(tr["t"] == t) & (tr["track"] == lab)]
        want = -2 if not lab else (["a", "b"].index(held[0]) if len(held) and held[0] else -1)
        assert serve[t - 1, j] == want


def test_a_one_target_component_is_refused_for_several_targets_and_unsimulated_options_are_named():
    from trackjam.simulation.engine import Simulation

    with pytest.raises(ConfigError, match="^targets: 2 targets given"):
        Simulation(two())
    for key, value in (("fusion.existence", "evidence"), ("control.plan_over", "belief"),
                       ("fusion.search_reseed", "evidence"), ("filter.reserve_memory", "1"), ("control.belief_at_least", "1"),
                       ("filter.velocity_jitter", "0.5"), ("filter.birth", "mixed"), ("filter.birth_prob", "0.5"),
                       ("filter.birth_mix", "0.3")):
        with pytest.raises(ConfigError, match=f"^{re.escape(key)}: .* not simulated with several targets"):
            SwarmSimulation(two(f"{key}={value}"))
    with pytest.raises(ConfigError, match=r"^control\.close_in: 0\.05 is not simulated with several targets yet; "
                                          r"the swarm engine runs with null$"):
        SwarmSimulation(two("control.close_in=0.05", solver="exact"))  # greedy would be refused with it anyway
    with pytest.raises(ConfigError, match=r"^filter\.visibility\.per_particle: .* not simulated with several targets"):
        SwarmSimulation(two("filter.visibility={hide: 0.05, reappear: 0.25, per_particle: true}"))
    SwarmSimulation(two("filter.visibility={hide: 0.05, reappear: 0.25}"))  # the mode itself is simulated
    with pytest.raises(ConfigError, match=r"^filter\.birth: 'measurement' .*; the swarm engine's LMB filters use their own "
                                          r"adaptive birth \(leave it at 'uniform'\)$"):
        SwarmSimulation(two("filter.birth=measurement"))


@pytest.mark.parametrize("table", list(SWARM_TABLES))
def test_the_docs_document_exactly_each_swarm_log(table):
    assert first_column_names(f"Several targets: `{table}.parquet`", SEVERAL_TARGETS) == {c.name for c in SWARM_TABLES[table]}


def test_write_run_writes_the_swarm_logs_its_figure_and_its_replay(run, tmp_path):
    import pyarrow.parquet as pq

    from trackjam.simulation.output import write_run

    files = write_run(run, tmp_path / "out")
    assert sorted(p.name for p in files) == sorted(
        ["scenario.yaml", "summary.json", "run.png", "replay.html", *(f"{name}.parquet" for name in SWARM_TABLES)])
    assert (tmp_path / "out" / "run.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = (tmp_path / "out" / "replay.html").read_text()
    assert page.startswith("<!doctype html>") and "<title>trackjam replay: " in page and 'id="trackjam-replay"' in page
    assert '"name":"target a"' in page and '"name":"target b"' in page
    logs_only = write_run(run, tmp_path / "logs", figures=False)
    assert not {"run.png", "replay.html"} & {p.name for p in logs_only}
    back = pq.read_table(tmp_path / "out" / "targets.parquet").to_pydict()
    assert back["target"] == list(run.tables["targets"]["target"])
    write_run(run, tmp_path / "out")  # the same run again into its own folder: allowed


def _track(label, e, x, s=1.0):
    from trackjam.estimation.lmb import TrackEstimate

    return TrackEstimate(label, e, np.r_[x, 0.0, 0.0, 0.0], np.eye(6) * s ** 2)


def test_a_cluster_is_fused_from_the_members_whose_cone_reached_it():
    from trackjam.estimation.bernoulli import Estimate
    from trackjam.estimation.fusion import fuse
    from trackjam.estimation.lmb_fusion import fuse_tracks
    from trackjam.simulation.swarm import informed_fusion

    own = [[_track((0, 0), 0.9, [10.0, 10, 10], 0.5)], [_track((0, 0), 0.8, [11.0, 10, 10], 2.0)],
           [_track((0, 0), 0.7, [10.0, 11, 10], 2.0)]]
    team = fuse_tracks(own)
    assert len(team) == 1 and len(team[0].members) == 3
    # only agent 0 saw it: the cluster is agent 0's track alone
    (f,) = informed_fusion(team, own, [np.array([True]), np.array([False]), np.array([False])])
    want = fuse([Estimate(0.9, own[0][0].mean, own[0][0].cov)])
    assert f.members == team[0].members and f.estimate.existence == want.existence
    np.testing.assert_array_equal(f.estimate.mean, want.mean)
    # every member informed, or none: the fusion of the whole cluster
    for flags in (True, False):
        (g,) = informed_fusion(team, own, [np.array([flags])] * 3)
        assert g is team[0]


def test_a_fused_tracks_visibility_is_its_members_mean():
    from trackjam.estimation.lmb import TrackEstimate
    from trackjam.estimation.lmb_fusion import fuse_tracks
    from trackjam.simulation.swarm import visible

    def tr(nu, x):
        return TrackEstimate((0, 0), 0.9, np.r_[x, 0.0, 0.0, 0.0], np.eye(6), nu)

    own = [[tr(0.2, [10.0, 10, 10])], [tr(0.6, [10.5, 10, 10])], []]
    (f,) = fuse_tracks(own)
    assert visible(f, own) == pytest.approx(0.4)


def test_the_hidden_target_mode_reaches_every_filter_and_the_report_needs_a_visible_track(monkeypatch):
    """filter.visibility on the swarm engine: each agent's LMB filter runs the mode, and a
    confirmed track is reported only while existence x P(visible) > 0.5 (the one-target rule);
    target a, hidden from step 3 on, is then withheld while its track stays confirmed."""
    import trackjam.simulation.swarm as swarm

    judged = []
    visible = swarm.visible

    def spy(track, own):
        v = visible(track, own)
        judged.append((swarm.track_label(track), track.estimate.existence * v > 0.5))
        return v

    monkeypatch.setattr(swarm, "visible", spy)
    sim = SwarmSimulation(two_targets("steps=8", "control.solver=greedy", "filter.visibility={hide: 0.05, reappear: 0.25}",
                                      "targets=[{id: a, initial: [20, 20, 20, 1.5, 2.0, 1.7], occlusions: [[3, 8]]},"
                                      " {id: b, initial: [60, 60, 60, -1, 0, 0]}]"))
    assert all(a.filter.p.visibility == (0.05, 0.25) for a in sim.agents)
    withheld = []
    for _ in range(8):
        judged.clear()
        r = sim.step()
        assert set(r.tracks["track"]) == {label for label, ok in judged if ok}
        withheld += [r.t for _, ok in judged if not ok]
    # the filters keep target a's track confirmed while they believe it hidden, and it is not reported
    assert withheld and min(withheld) >= 3


@pytest.mark.parametrize("share", ["posteriors", "scans"])
def test_under_share_scans_every_agent_updates_on_every_teammates_scan(share, monkeypatch):
    """fusion.share: scans hands each filter the N - 1 teammates' scans of the step, each taken
    from that teammate's position with its antenna's pointing and level."""
    seen = []
    update = LMBFilter.update

    def spy(self, Z, u, aim, level_w, others=()):
        seen.append([(o.u.copy(), o.Z.shape) for o in others])
        return update(self, Z, u, aim, level_w, others)

    monkeypatch.setattr(LMBFilter, "update", spy)
    sim = SwarmSimulation(two(f"fusion.share={share}"))
    r = sim.step()
    assert len(seen) == 3
    for j, others in enumerate(seen):
        if share == "posteriors":
            assert others == []
            continue
        mates = [k for k in range(3) if k != j]
        assert [tuple(u) for u, _ in others] == [tuple(sim.agents[k].position) for k in mates]
        assert [shape[0] for _, shape in others] == [r.agents["measurements"][k] for k in mates]


def test_the_assignment_search_stops_at_the_node_budget():
    capped = simulate(two("control.node_limit=1", "control.time_limit_s=3600", solver="exact"))
    free = simulate(two("control.time_limit_s=3600", solver="exact"))
    planned = capped.steps["mode"] != "hover"
    assert planned.any() and not capped.steps["optimal"][planned].any()
    assert free.steps["optimal"][free.steps["mode"] != "hover"].all()


def test_the_swarm_presets_list_their_targets():
    from trackjam.config import preset_names, scenario_to_yaml

    swarms = [n for n in preset_names() if n.startswith("swarm-")]
    assert "swarm-3" in swarms
    for name in swarms:
        s = load_scenario(name)
        assert len(s.target_list) == int(name.split("-")[1]) and "targets:" in scenario_to_yaml(s)
        SwarmSimulation(s)  # every option it sets is one the swarm engine simulates


@pytest.mark.parametrize("objective", ["sum", "min"])
def test_the_team_objective_is_the_configured_one(monkeypatch, objective):
    """control.team_objective reaches every step's assignment problem, and the logged objective
    is that rule over the targets' Xi_k."""
    import trackjam.simulation.swarm as swarm

    seen = []
    build = swarm.build_assignment

    def spy(*args, **kw):
        problem = build(*args, **kw)
        seen.append(problem.objective)
        return problem

    monkeypatch.setattr(swarm, "build_assignment", spy)
    r = simulate(two(f"control.team_objective={objective}", solver="exact"))
    assert seen and set(seen) == {objective}
    assert np.all(np.isfinite(r.steps["objective"][r.steps["mode"] == "track"]))


def test_cue_tracks_with_velocities_predict_to_the_first_position():
    """filter.cue.velocity: target: particles around [x - v, v], whose Eq. (1) prediction
    (x + v, before noise) is the first position x."""
    s = two("filter.particles=4000")
    lmb = LMBFilter(lmb_params(s), build_swarm(s).base.antenna, np.random.default_rng(0))
    first = np.array([[20.0, 20, 20], [60, 60, 60]])
    v = np.array([[1.5, -2.0, 0.5], [0.0, 3.0, -1.0]])
    tracks = cue_tracks(lmb, first, [True, True], (0.9, 2.0, 1.0), v)
    for k, track in enumerate(tracks):
        mean, cov = weighted_moments(track.X, np.exp(track.log_w))
        np.testing.assert_allclose(mean, np.concatenate([first[k] - v[k], v[k]]), atol=0.2)
        np.testing.assert_allclose(np.sqrt(np.diag(cov)), [2.0] * 3 + [1.0] * 3, rtol=0.06)
        predicted = track.X[:, :3] + track.X[:, 3:6]
        np.testing.assert_allclose(np.average(predicted, axis=0, weights=np.exp(track.log_w)), first[k], atol=0.25)


def test_the_swarm_cue_velocity_is_each_targets_first_velocity():
    s = two("filter.particles=2000", "filter.cue.velocity=target")
    sim = SwarmSimulation(s)
    v = np.array([t.initial[3:6] for t in s.targets])
    for a in sim.agents:
        for track in a.filter.tracks:
            k = track.label[1]
            np.testing.assert_allclose(np.average(track.X[:, 3:6], axis=0, weights=np.exp(track.log_w)), v[k], atol=0.2)


def test_a_text_id_with_dollar_signs_is_drawn_as_written(tmp_path):
    # matplotlib read "$\frac{$" as mathtext: the figure failed with a ParseSyntaxException
    # after the whole run, and `trackjam run` wrote nothing
    from trackjam.simulation.output import write_run

    ids = ["targets=[{id: '$\\frac{$', initial: [20, 20, 20, 1.5, 2.0, 1.7]}, {id: '$x$', initial: [60, 60, 60, -1, 0, 0]}]"]
    run = simulate(two("steps=2", *ids))
    files = write_run(run, tmp_path / "out")
    assert (tmp_path / "out" / "run.png") in files


def test_the_swarm_figure_says_what_its_agent_numbers_and_its_step_axis_are(run, tmp_path, monkeypatch):
    # run.png of a swarm run numbered each agent's path end without a word, and its time axis was
    # a bare "step" where the one-target figure says "time step t  (dT = 1 s)"
    import trackjam.viz.swarm as viz
    from trackjam.simulation.build import figure_settings

    drawn = []
    monkeypatch.setattr(viz, "save_figure", lambda fig, path, **kwargs: drawn.append(fig))
    viz.plot_swarm(run.tables, figure_settings(run.scenario), tmp_path / "run.png")
    (fig,) = drawn
    area = fig.axes[0]
    assert "numbered at their end" in area.get_title()
    assert [t.get_text() for t in area.texts] == ["1", "2", "3"]  # the three agents' numbers
    assert fig.axes[-1].get_xlabel() == "time step t  (dT = 1 s)"
    # each target's path has a marker where it appears, so that its direction shows
    starts = [(ln.get_xdata()[0], ln.get_ydata()[0]) for ln in area.get_lines() if ln.get_gid() == "target start"]
    tg = run.tables["targets"]
    first = [(tg["truth_x"][tg["target"] == k][0], tg["truth_y"][tg["target"] == k][0]) for k in ("a", "b")]
    np.testing.assert_allclose(starts, first)
    assert "where a target appears" in [t.get_text() for t in area.get_legend().get_texts()]
