"""The comms faults on the swarm engine (several targets): with none, the per-agent path is the
team's one solve bit for bit; lost messages leave an agent on its own tracks; a broken agent
stays put, silent and deaf; late posteriors are dropped or coasted by Eq. (1), late scans weighed
at the retrodicted particles; one seed gives one run."""

import numpy as np
import pytest

from trackjam.estimation.bernoulli import Scan
from trackjam.estimation.lmb import Track, TrackEstimate, lmb_update, retrodicted
from trackjam.radio.antenna import AntennaModel
from trackjam.simulation.agent import Message
from trackjam.simulation.swarm import SwarmSimulation, coasted_tracks

from swarm_scenarios import two_targets

N = 3  # agents of the two-target scenario


def two(*extra, solver="exact", steps=5):
    return two_targets(f"steps={steps}", f"control.solver={solver}", *extra)


def run(scenario, distributed=None, actions=None):
    sim = SwarmSimulation(scenario)
    if distributed is not None:
        sim.distributed = distributed
        sim.reset()
    views = []
    while not sim.done:
        sim.step(None if actions is None else actions(sim))
        views.append((sim.predicted_views, sim.views, [a.filter.estimates() for a in sim.agents]))
    return sim, sim.result(), views


def same_tables(a, b):
    """Every column but the wall times, bit for bit (NaN equal to NaN)."""
    for table, cols in a.tables.items():
        assert list(cols) == list(b.tables[table])
        for k, x in cols.items():
            if not k.endswith("_s"):
                y = b.tables[table][k]
                assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), (table, k)


def members_of(view):
    return {agent for f in view for agent, _ in f.members}


@pytest.mark.parametrize("extra", [("fusion.share=posteriors", "fusion.feedback=true"),
                                   ("fusion.share=scans", "control.fallback=search"),
                                   ("antenna.pointing=truth",),
                                   ("control.solver=grasp", "control.grasp.samples=40", "control.grasp.iterations=3")])
def test_without_faults_every_agent_planning_from_its_own_view_is_the_teams_one_solve_bit_for_bit(extra):
    s = two(*extra)
    single, a, _ = run(s)
    assert not single.distributed  # no fault: the team's one solve
    per_agent, b, _ = run(s, distributed=True)
    same_tables(a, b)
    assert np.all(a.agents["heard"] == N)
    _, c, _ = run(two(*extra, "comms.loss=0"))  # given explicitly
    assert s.control.solver == ("grasp" if "control.solver=grasp" in extra else "exact")
    same_tables(a, c)


def test_the_exchange_draws_nothing_the_run_reads_when_no_message_is_lost():
    # a failure after the last step puts the run on the per-agent path, whose exchange draws its
    # losses each round from the comms stream: the run is still the faultless one
    _, a, _ = run(two())
    sim, b, _ = run(two("comms.failures=[{agent: 1, step: 99, mode: breakdown}]"))
    assert sim.distributed
    same_tables(a, b)


def test_with_every_message_lost_each_agent_fuses_plans_and_reports_from_its_own_tracks_only():
    sim, r, views = run(two("comms.loss=1.0", "fusion.share=posteriors"))
    assert np.all(r.agents["heard"] == 1)
    for predicted, fused, filters in views:
        for j in range(N):
            assert members_of(predicted[j]) <= {j} and members_of(fused[j]) <= {j}
            # fusing one agent's tracks alone gives them back, one cluster per track
            own = {e.label: e for e in filters[j]}
            assert sorted(label for f in fused[j] for _, label in f.members) == sorted(own)
            for f in fused[j]:
                (_, label), = f.members
                assert f.estimate.existence == own[label].existence
                if f.estimate.mean is not None:
                    assert np.allclose(f.estimate.mean, own[label].mean)
    # the team's report is agent 0's view: every reported track is one of its own
    assert all(t.startswith("a0:") for t in r.tables["tracks"]["track"])
    assert np.all(r.tables["tracks"]["members"] == 1)


GRASP = ("control.grasp.samples=40", "control.grasp.iterations=3", "control.grasp.threads=2")


@pytest.mark.parametrize("solver, extra", [("exact", ()), ("grasp", GRASP)])
def test_some_lost_messages_leave_agents_with_different_views_and_one_seed_gives_one_run(solver, extra):
    # under grasp a row that is not the planner's searches with a stream spawned from the planner's
    s = two("comms.loss=0.3", *extra, solver=solver, steps=8)
    _, a, _ = run(s)
    _, b, _ = run(s)
    same_tables(a, b)
    heard = a.agents["heard"]
    assert heard.min() >= 1 and heard.max() <= N and heard.min() < N  # some message lost, some arrived
    _, c, _ = run(two("comms.loss=0.3", "seed=2", *extra, solver=solver, steps=8))
    assert not np.array_equal(c.agents["heard"], heard)


def test_a_broken_agent_stays_put_and_neither_transmits_scans_nor_sends_from_its_failure_step():
    sim, r, views = run(two("comms.failures=[{agent: 1, step: 3, mode: breakdown}]", "fusion.share=posteriors"))
    ag = r.agents
    t, j = ag["t"], ag["agent"]
    down = (j == 1) & (t >= 3)
    assert np.all(ag["mode"][down] == "down") and not np.any(ag["mode"][~down] == "down")
    for a in "xyz":
        assert np.array_equal(ag[a][down], ag[f"prev_{a}"][down])
    assert np.all(ag["power_w"][down] == 0.0) and np.all(ag["measurements"][down] == 0)
    assert np.all(ag["heard"][down] == 0) and np.all(ag["tracks"][down] == 0)
    assert np.all(ag["heard"][(t >= 3) & (j != 1)] == N - 1) and np.all(ag["heard"][t < 3] == N)
    assert not np.any(r.tables["measurements"]["agent"][r.tables["measurements"]["t"] >= 3] == 1)
    for step, (predicted, fused, _) in enumerate(views, start=1):
        for k in (0, 2):
            assert (1 in members_of(predicted[k])) == (step < 3)
            assert (1 in members_of(fused[k])) == (step < 3)
    assert sim.agents[1].position.tolist() == [ag[a][(j == 1) & (t == 2)][0] for a in "xyz"]


@pytest.mark.parametrize("mode, hears, heard_by_others", [("publisher", N, N - 1), ("channel", 1, N - 1)])
def test_a_lost_publisher_still_hears_the_team_a_lost_channel_hears_nobody(mode, hears, heard_by_others):
    _, r, views = run(two(f"comms.failures=[{{agent: 2, step: 2, mode: {mode}}}]"))
    ag = r.agents
    late = ag["t"] >= 2
    assert np.all(ag["heard"][late & (ag["agent"] == 2)] == hears)
    assert np.all(ag["heard"][late & (ag["agent"] != 2)] == heard_by_others)
    assert not np.any(ag["mode"] == "down")
    for predicted, _, _ in views[1:]:
        assert 2 not in members_of(predicted[0]) and 2 not in members_of(predicted[1])


def test_coasting_a_late_posterior_predicts_each_track_by_eq_1_from_the_senders_latest_message():
    q = 0.5
    mean = np.array([10.0, 20.0, 30.0, 1.0, -2.0, 0.5])
    tracks = [TrackEstimate((0, 0), 0.8, mean, np.zeros((6, 6)), 0.9)]
    old = Message(1, "posterior", 3, tracks=[TrackEstimate((0, 0), 0.3, mean + 100, np.eye(6))])
    m = Message(1, "posterior", 4, tracks=tracks, informed=np.array([True]))
    other = Message(2, "posterior", 5, tracks=[])
    out = coasted_tracks([m, old, other], 6, q)
    assert [x.sender for x in out] == [1, 2]  # each sender's latest, in sender order
    (e,) = out[0].tracks
    assert (e.label, e.existence, e.visible) == ((0, 0), 0.8, 0.9) and out[0].informed.tolist() == [True]
    # two steps of Eq. (1) from a state known exactly: x + 2 v; Q = q Gamma Gamma' twice
    assert np.allclose(e.mean, [12.0, 16.0, 31.0, 1.0, -2.0, 0.5])
    P = e.cov
    assert np.allclose(np.diag(P), [2.5 * q] * 3 + [2.0 * q] * 3)
    assert np.allclose([P[0, 3], P[1, 4], P[2, 5]], [2.0 * q] * 3)
    assert P[0, 1] == 0.0


def test_a_late_posterior_is_fused_under_coast_and_dropped_under_drop():
    for stale in ("coast", "drop"):
        _, r, views = run(two("comms.delay_steps=1", f"comms.stale={stale}", "fusion.share=posteriors"))
        assert np.all(r.agents["heard"] == 1)  # a late prediction gives a position, never a plan
        for step, (predicted, fused, _) in enumerate(views, start=1):
            for j in range(N):
                assert members_of(predicted[j]) <= {j}
                others = members_of(fused[j]) - {j}
                if stale == "drop" or step == 1:
                    assert not others
        if stale == "coast":  # from step 2 on, the teammates' posteriors of the step before
            assert any(members_of(fused[j]) - {j} for _, fused, _ in views[1:] for j in range(N))


def test_the_lmb_filter_weighs_a_late_scan_at_its_particles_retrodicted_to_the_scans_step():
    from trackjam.config import load_scenario
    from trackjam.simulation.build import antenna_model

    ant: AntennaModel = antenna_model(load_scenario("paper-fig3"))
    rng = np.random.default_rng(3)
    n = 400
    X = np.concatenate([rng.normal([50, 50, 50], 1.0, (n, 3)), rng.normal([2.0, 0.0, 0.0], 0.3, (n, 3))], axis=1)
    track = Track((1, 0), 0.6, X, np.full(n, -np.log(n)))
    u, aim = np.array([40.0, 50.0, 50.0]), np.array([46.0, 50.0, 50.0])
    Z = np.array([[6.0, 0.0, np.pi / 2]])  # one detection where the target was two steps ago
    scan = Scan.of(Z, u, aim, ant.l_max, ant)
    args = (ant, np.array([0.8, 0.06, 0.06]), np.log(1e-6))
    late, _, _ = lmb_update([track], scan.late(2), *args, np.random.default_rng(0), "ranked")
    back, _, _ = lmb_update([retrodicted(track, 2)], scan, *args, np.random.default_rng(0), "ranked")
    now, _, _ = lmb_update([track], scan, *args, np.random.default_rng(0), "ranked")
    assert late[0].r == back[0].r and np.array_equal(late[0].log_w, back[0].log_w)
    assert np.array_equal(late[0].X, X)  # weighed there, kept here
    assert late[0].r != now[0].r


def test_late_scans_are_weighed_under_coast_and_ignored_under_drop():
    for stale in ("coast", "drop"):
        sim, r, _ = run(two("comms.delay_steps=1", f"comms.stale={stale}", "fusion.share=scans"))
        assert len(r.steps["t"]) == 5
    a = run(two("comms.delay_steps=1", "comms.stale=coast", "fusion.share=scans"))[1]
    b = run(two("comms.delay_steps=1", "comms.stale=drop", "fusion.share=scans"))[1]
    # step 1 is the same (nothing has arrived yet); the late scans change a later filter
    assert a.tables["tracks"]["existence"][a.tables["tracks"]["t"] == 1].tolist() == \
        b.tables["tracks"]["existence"][b.tables["tracks"]["t"] == 1].tolist()
    assert not np.array_equal(a.tables["tracks"]["existence"], b.tables["tracks"]["existence"])


def test_given_actions_apply_to_the_working_agents_and_a_broken_one_stays_down():
    s = two("comms.loss=0.5", "comms.failures=[{agent: 0, step: 2, mode: breakdown}]")

    def act(sim):
        labels = [track_label_of(f) for f in sim.sure]
        serve = labels[0] if labels else ""
        return np.array([1, 1, 0]), np.array([3, 3, 0]), [serve, serve, ""]

    _, r, _ = run(s, actions=act)
    ag = r.agents
    down = (ag["agent"] == 0) & (ag["t"] >= 2)
    assert np.all(ag["mode"][down] == "down") and np.all(ag["power_w"][down] == 0.0)
    assert np.all(ag["level_index"][(ag["agent"] == 1)] == 3) and np.all(r.steps["mode"][1:] == "external")
    for a in "xyz":
        assert np.array_equal(ag[a][down], ag[f"prev_{a}"][down])


def track_label_of(f):
    from trackjam.simulation.swarm import track_label

    return track_label(f)


def test_the_resource_estimate_counts_a_view_per_agent_under_the_faults():
    from trackjam.config import load_scenario
    from trackjam.config.limits import estimate

    base = estimate(load_scenario("swarm-3"))
    n = 5  # swarm-3's agents
    for item in ("comms.loss=0.1", "comms.delay_steps=1", "comms.failures=[{agent: 0, step: 3, mode: channel}]"):
        faulty = estimate(load_scenario("swarm-3", [item]))
        assert faulty["work_tables"][0] == n * base["work_tables"][0], item
        assert faulty["work_fusion"][0] == n * base["work_fusion"][0], item
    assert "memory_messages" not in base
    late = estimate(load_scenario("swarm-3", ["comms.delay_steps=2"]))["memory_messages"][0]
    assert late == 2 * estimate(load_scenario("swarm-3", ["comms.delay_steps=1"]))["memory_messages"][0] > 0


def test_the_docs_measurement_script_reads_one_runs_held_shares_and_ospa():
    import importlib.util
    from pathlib import Path

    from trackjam.config import load_scenario
    from trackjam.simulation.loop import simulate

    path = Path(__file__).resolve().parents[2] / "docs" / "swarm_comms.py"
    spec = importlib.util.spec_from_file_location("swarm_comms", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    small = ["steps=3", "filter.particles=300", "filter.birth_particles=100", "comms.loss=0.5"]
    row = mod.figures(small, 4)
    s = simulate(load_scenario("swarm-3", [*small, "seed=4"])).summary
    assert row == [100.0 * v for v in s["held_share"]] + [100.0 * s["held_share_total"], s["ospa_mean"]]
    m, h = mod.ci95(np.array([1.0, 2.0, 4.0]))
    assert m == pytest.approx(7 / 3) and h > 0
    assert list(mod.VARIANTS)[0] == "every message" and mod.VARIANTS["every message"] == []


def test_once_every_agent_is_down_nothing_is_reported_and_nobody_transmits():
    down = "comms.failures=[" + ", ".join(f"{{agent: {j}, step: 3, mode: breakdown}}" for j in range(N)) + "]"
    sim, r, views = run(two(down))
    late = r.steps["t"] >= 3
    assert np.all(r.steps["mode"][late] == "down") and not np.any(r.steps["mode"][~late] == "down")
    assert np.all(r.steps["tracks"][late] == 0) and np.all(r.steps["aims"][late] == 0)
    detectable = r.steps["targets_detectable"][late] > 0
    assert np.all(r.steps["ospa"][late][detectable] == sim.c.base.ospa_cutoff)  # every target missed
    assert not np.any(r.tables["tracks"]["t"] >= 3) and np.all(r.agents["power_w"][r.agents["t"] >= 3] == 0.0)
    assert all(not v for _, fused, _ in views[2:] for v in fused)
