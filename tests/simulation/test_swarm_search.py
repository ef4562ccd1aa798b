"""The swarm engine's aims and its search for lost targets: a lost track stays a search aim,
coasted by Eq. (1), for SEARCH_STEPS steps; control.lead, control.horizon and
fusion.report_spread reach the step; the old defaults plan where they did."""

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

import trackjam.simulation.swarm as swarm
from trackjam.control.pursuit import AimSettings, aim_ahead
from trackjam.estimation.lmb_fusion import GATE
from trackjam.simulation.swarm import SwarmSimulation, confirmed
from trackjam.simulation.swarm_search import SEARCH_STEPS, Aim, SearchMemory, plan_point
from trackjam.world.motion import cv_coast

from swarm_scenarios import two_targets



def two(*extra):
    return two_targets("steps=8", "control.solver=greedy", *extra)


def state(x, v=(0.0, 0.0, 0.0)):
    return np.r_[np.asarray(x, float), np.asarray(v, float)]


def confirmed_aim(label, x, s=1.0):
    m = state(x)
    return Aim(label, m, np.eye(6) * s**2, m[:3])


def test_a_lost_track_is_searched_at_its_coasted_state_for_search_steps_steps():
    mem = SearchMemory(accel_var=0.5)
    m, P = state([50, 50, 50], [1, -2, 0.5]), np.eye(6)
    mem.remember(3, [("a0:0.0", m, P)])
    for t in range(4, 4 + SEARCH_STEPS + 3):
        lost = mem.lost(t, [])
        if t - 3 <= SEARCH_STEPS:
            (label, x, C), = lost
            want = cv_coast(m, P, 0.5, t - 3)
            assert label == "a0:0.0"
            np.testing.assert_allclose(x, want[0]) and np.testing.assert_allclose(C, want[1])
        else:
            assert lost == []
        mem.remember(t, [])
    assert mem.last == {}  # forgotten once it can no longer be searched


def test_a_search_aim_ends_when_its_track_or_another_near_it_is_confirmed():
    mem = SearchMemory(accel_var=0.5)
    mem.remember(1, [("lost", state([50, 50, 50]), np.eye(6))])
    assert [x for x, _, _ in mem.lost(2, [confirmed_aim("lost", [10, 10, 10])])] == []
    # the target re-found under another label: a confirmed track within the gate
    assert mem.lost(2, [confirmed_aim("new", [51, 50, 50])]) == []
    # a confirmed track elsewhere leaves the search aim in place
    assert [x for x, _, _ in mem.lost(2, [confirmed_aim("other", [80, 50, 50])])] == ["lost"]


def test_two_lost_tracks_of_one_target_give_one_search_aim_the_more_recent():
    mem = SearchMemory(accel_var=0.5, gate=GATE)
    mem.remember(1, [("old", state([50, 50, 50]), np.eye(6))])
    mem.remember(2, [("new", state([50.5, 50, 50]), np.eye(6))])
    mem.remember(3, [("far", state([10, 80, 50]), np.eye(6))])
    assert [x for x, _, _ in mem.lost(4, [])] == ["far", "new"]


def test_the_plan_point_moves_ahead_by_lead_and_stays_in_the_area():
    low, high = np.zeros(3), np.full(3, 100.0)
    m = state([50, 50, 98], [1, 2, 3])
    np.testing.assert_array_equal(plan_point(m, np.zeros((1, 3)), AimSettings(), low, high), m[:3])
    np.testing.assert_allclose(plan_point(m, np.zeros((1, 3)), AimSettings(lead=2.0), low, high), [52, 54, 100])


def _spy(monkeypatch):
    """Records each step's fused predicted tracks (the step's first fusion of two) and the aims
    x_bar_k handed to the solver, by step."""
    seen = {"fused": [], "x_bar": {}}
    fuse, build = swarm.fuse_tracks_unchecked, swarm.build_assignment

    def fuse_spy(tracks, *a, **kw):
        seen["fused"].append(fuse(tracks, *a, **kw))
        return seen["fused"][-1]

    def build_spy(positions, aims, *a, **kw):
        seen["x_bar"][(len(seen["fused"]) + 1) // 2] = np.array(aims)
        return build(positions, aims, *a, **kw)

    monkeypatch.setattr(swarm, "fuse_tracks_unchecked", fuse_spy)
    monkeypatch.setattr(swarm, "build_assignment", build_spy)
    return seen


def predicted(seen, t):
    # the first fusion is reset's (the cue's tracks, what a controller may serve), then two a step
    return seen["fused"][2 * (t - 1) + 1]


@pytest.mark.parametrize("extra, lead", [((), 0.0), (("control.lead=1.5",), 1.5), (("control.horizon=4",), None)])
def test_the_aims_are_the_confirmed_predictions_moved_ahead_by_lead_and_horizon(monkeypatch, extra, lead):
    """With the old defaults (lead 0, horizon 1, hover) x_bar_k is the confirmed predicted
    tracks' fused positions, as before these options; lead and horizon reach every step."""
    seen = _spy(monkeypatch)
    sim = SwarmSimulation(two(*extra))
    ahead = 0
    while not sim.done:
        before = sim.positions
        sim.step()
        if sim.t not in seen["x_bar"]:
            continue
        sure = confirmed(predicted(seen, sim.t))[:swarm.MAX_AIMS]
        means = np.array([f.estimate.mean for f in sure])
        if lead is not None:
            want = np.clip(means[:, :3] + lead * means[:, 3:6], 0, 100)
        else:
            settings = sim.c.base.team.aim
            assert settings.horizon == 4
            want = np.array([np.clip(aim_ahead(m[:3], m[3:6], before, settings), 0, 100) for m in means])
        np.testing.assert_allclose(seen["x_bar"][sim.t], want, rtol=0, atol=1e-12)
        ahead += not np.allclose(want, means[:, :3])
    assert len(seen["x_bar"]) >= 4 and (ahead > 0) == bool(extra)


def _lose_track(sim, k):
    """Every agent's filter forgets the cued track of target k (as if misses had killed it)."""
    for a in sim.agents:
        a.filter.tracks = [replace(t, r=0.0) if t.label == (0, k) else t for t in a.filter.tracks]


def test_a_lost_track_becomes_a_search_aim_that_agents_serve_and_log(monkeypatch):
    seen = _spy(monkeypatch)
    sim = SwarmSimulation(two("control.fallback=search"))
    first = sim.step()
    (label,) = [lab for lab, tg in zip(first.tracks["track"], first.tracks["target"]) if tg == "b"]
    kept = sim.memory.last[label]
    assert kept[0] == 1
    _lose_track(sim, 1)
    r = sim.step()
    x_bar = seen["x_bar"][2]
    coasted = cv_coast(kept[1], kept[2], sim.c.base.team.accel_var, 1)[0]
    assert r.step["aims"] == len(x_bar) and np.any(np.all(np.isclose(x_bar, coasted[:3]), axis=1))
    searching = [j for j, lab in enumerate(r.agents["serves"]) if lab == label]
    assert searching and all(r.agents["mode"][j] == "search" for j in searching)
    assert all(m == "track" for j, m in enumerate(r.agents["mode"]) if j not in searching)
    assert list(first.agents["mode"]) == ["track"] * 3
    # under hover the lost track is simply dropped
    seen = _spy(monkeypatch)
    hover = SwarmSimulation(two())
    hover.step()
    _lose_track(hover, 1)
    r = hover.step()
    assert label not in r.agents["serves"] and not np.any(np.all(np.isclose(seen["x_bar"][2], coasted[:3]), axis=1))


def test_with_every_track_lost_the_team_searches_instead_of_hovering():
    sim = SwarmSimulation(two("control.fallback=search"))
    sim.step()
    for k in (0, 1):
        _lose_track(sim, k)
    r = sim.step()
    # the solver planned (a hovering team has no objective) at the two search aims
    assert r.step["mode"] == "search" and set(r.agents["mode"]) == {"search"}
    assert r.step["aims"] == 2 and np.isfinite(r.step["objective"])


def test_report_spread_reports_only_the_tight_confirmed_tracks():
    wide = SwarmSimulation(two("fusion.report_spread=0.01"))
    free = SwarmSimulation(two())
    for _ in range(3):
        r, q = wide.step(), free.step()
        # the same run (the option only filters the report) reporting nothing that spread
        np.testing.assert_array_equal(r.agents["pos"], q.agents["pos"])
        assert r.step["tracks"] == 0 and q.step["tracks"] > 0 and r.step["aims"] == q.step["aims"] > 0


@pytest.mark.parametrize("key, value", [("control.lead", "-1"), ("control.fallback", "seek"),
                                        ("fusion.report_spread", "0"), ("control.horizon", "0")])
def test_bad_values_of_the_options_exit_2_with_one_line(tmp_path, key, value):
    r = subprocess.run([sys.executable, "-m", "trackjam", "run", "swarm-3", "--out", str(tmp_path / "o"),
                        "--set", f"{key}={value}"], capture_output=True, text=True)
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert r.returncode == 2 and len(lines) == 1 and key in lines[0] and "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()


def test_the_search_changes_nothing_until_a_track_is_lost():
    """Runs with hover and with search are the same step for step while the search has no aim
    to add (the memory only ever adds aims)."""
    hover, search = SwarmSimulation(two("steps=12")), SwarmSimulation(two("steps=12", "control.fallback=search"))
    same, added = 0, False
    while not hover.done and not added:
        r, q = hover.step(), search.step()
        if q.step["aims"] != r.step["aims"]:
            added = q.step["aims"] > r.step["aims"] and "search" in list(q.agents["mode"])
            assert added
            continue
        for k in ("pos", "level_index", "point", "serves", "detections"):
            np.testing.assert_array_equal(np.asarray(r.agents[k]), np.asarray(q.agents[k]), err_msg=k)
        assert r.tracks["track"] == q.tracks["track"]
        same += 1
    assert same >= 2 and added  # on this seed a track is lost at step 4 and searched for
