"""The several-target environment (swarm engine): PettingZoo's API and seed tests on swarm-3 and
a small two-target scenario, one episode per seed, the reward against the logged geometry, the
slot -> track mapping, the action mask, the solver policies giving simulate's run, and one clear
error for every bad action."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from trackjam.config import load_scenario
from trackjam.env import (
    Planned,
    SwarmParallelEnv,
    parallel_env,
    random_policy,
    rollout,
    solver_policy,
    swarm_observation_layout,
    swarm_state_layout,
)
from trackjam.radio.antenna import detection_probability, interference_matrix
from trackjam.simulation.loop import simulate
from trackjam.simulation.swarm import SwarmSimulation, track_label

from swarm_scenarios import two_targets
from test_env_reward import xi_by_subsets

SWARM = ["steps=4", "filter.particles=300", "filter.birth_particles=60"]
TIMING = {"solve_s", "step_s"}


def swarm_env(*extra, **kw):
    return parallel_env(load_scenario("swarm-3", SWARM + list(extra)), **kw)


def two_env(*extra, **kw):
    return parallel_env(two_targets("steps=5", "control.solver=exact", *extra), **kw)


def episode(env, seed, policy_seed):
    """Observations, rewards and infos of one episode of the random policy."""
    policy = random_policy(env, policy_seed)
    obs, infos = env.reset(seed=seed)
    seen, rewards, told = [obs], [], [infos]
    while env.agents:
        obs, rew, _, _, infos = env.step(policy(obs))
        seen.append(obs)
        rewards.append(rew)
        told.append(infos)
    return seen, rewards, told


@pytest.mark.parametrize("make", [swarm_env, two_env], ids=["swarm-3", "two-targets"])
def test_passes_the_pettingzoo_parallel_api_and_seed_tests(make):
    env = make()
    assert isinstance(env, SwarmParallelEnv)
    parallel_api_test(env, num_cycles=5)
    parallel_seed_test(make, num_cycles=5)


def test_spaces_and_layouts_on_swarm_3():
    env = swarm_env()
    b = env.sim.c.base
    n_moves, n_levels = len(b.displacements), len(b.antenna.levels_w)
    assert env.possible_agents == [f"agent_{j}" for j in range(5)] and env.track_slots == 4
    assert env.action_space("agent_4").nvec.tolist() == [n_moves, n_levels, 5]
    names = swarm_observation_layout(5, 4)
    assert len(names) == len(set(names)) == env.observation_space("agent_0").shape[0] == 3 + 10 * 4 + 5 * 4 + 1
    state = swarm_state_layout(5, 3)
    assert len(state) == len(set(state)) == env.state_space.shape[0] == 4 * 5 + 9 * 3 + 1
    assert env.target_ids == ["a", "b", "c"]
    wide = swarm_env(track_slots=7)
    assert wide.action_space("agent_0").nvec[2] == 8 and wide.observation_space("agent_0").shape == (len(
        swarm_observation_layout(5, 7)),)


@pytest.mark.parametrize("bad", [0, -1, 65, 2.0, True, "4"])
def test_a_bad_number_of_slots_is_named(bad):
    with pytest.raises(ValueError, match=r"^track_slots: expected a whole number in \[1, 64\]"):
        swarm_env(track_slots=bad)


def test_same_seed_same_episode_and_another_seed_another():
    a_obs, a_rew, _ = episode(two_env(), seed=5, policy_seed=2)
    b_obs, b_rew, _ = episode(two_env(), seed=5, policy_seed=2)
    assert len(a_obs) == 6
    for x, y in zip(a_obs, b_obs):
        for agent in x:
            assert np.array_equal(x[agent], y[agent])
    assert a_rew == b_rew
    c_obs, _, _ = episode(two_env(), seed=6, policy_seed=2)
    assert not all(np.array_equal(x["agent_0"], y["agent_0"]) for x, y in zip(a_obs[1:], c_obs[1:]))


def test_the_observation_holds_the_position_the_teams_tracks_in_slots_and_the_teammates():
    env = two_env()
    obs, infos = env.reset(seed=2)
    names = swarm_observation_layout(3, 4)
    sim = env.sim
    tracks = sim.sure
    assert len(tracks) == 2  # the cue's: one per target, as the engine plans at them
    assert infos["agent_0"]["slots"] == [track_label(f) for f in tracks] + ["", ""]
    obs, _, _, _, infos = env.step({"agent_0": [0, 1, 1], "agent_1": [0, 1, 1], "agent_2": [0, 0, 0]})
    for j, a in enumerate(env.possible_agents):
        o = dict(zip(names, obs[a]))
        np.testing.assert_allclose([o["own.x"], o["own.y"], o["own.z"]], sim.positions[j], atol=1e-5)
        mates = [k for k in range(3) if k != j]
        for slot, k in enumerate(mates, start=1):  # every message arrives: where it is now
            np.testing.assert_allclose([o[f"mate{slot}.{c}"] for c in "xyz"], sim.positions[k], atol=1e-5)
            assert o[f"mate{slot}.received"] == 1 and o[f"mate{slot}.age"] == 0
        shown = infos[a]["slots"]
        for s, f in enumerate(sim.sure[:4], start=1):
            assert o[f"track{s}.occupied"] == 1 and shown[s - 1] == track_label(f)
            np.testing.assert_allclose([o[f"track{s}.{v}"] for v in ("x", "y", "z", "vx", "vy", "vz")],
                                       f.estimate.mean, rtol=1e-5, atol=1e-4)
            assert o[f"track{s}.e"] == pytest.approx(f.estimate.existence, rel=1e-6)
            members = {f"a{g}:{b}.{i}" for g, (b, i) in f.members}
            assert o[f"track{s}.served"] == (sim.agents[j].serves in members)
            assert o[f"track{s}.servers"] == pytest.approx(sum(x.serves in members for x in sim.agents) / 3)
        for s in range(len(sim.sure) + 1, 5):
            assert not any(v for k, v in o.items() if k.startswith(f"track{s}.")) and shown[s - 1] == ""
        assert o["time"] == pytest.approx(1 / 5)
        assert env.observation_space(a).contains(obs[a])
    # agents 0 and 1 served slot 1's track, agent 2 none
    assert sum(dict(zip(names, obs["agent_0"]))[f"track{s}.servers"] for s in range(1, 5)) == pytest.approx(2 / 3)


def test_a_slot_names_the_track_it_showed_when_the_agent_acted():
    # the slots are sorted by existence after every step, so a slot's track moves; the action's
    # slot names the label the observation showed, not what the slot holds after the step, and
    # the engine serves the predicted team track that holds that label, whatever its own label
    env = swarm_env("steps=8")
    obs, infos = env.reset(seed=3)
    predicted = []
    real = env.sim._given
    env.sim._given = lambda tracks, *a: (predicted.append(tracks), real(tracks, *a))[1]
    rng = np.random.default_rng(0)
    moved = regrouped = False
    while env.agents:
        before = infos["agent_0"]["slots"]
        slots = {a: int(rng.integers(1, 1 + sum(1 for s in before if s))) if any(before) else 0 for a in env.agents}
        actions = {a: np.array([0, 2, slots[a]]) for a in env.agents}
        obs, _, _, _, infos = env.step(actions)
        holder = {f"a{g}:{b}.{i}": track_label(f) for f in predicted[-1] for g, (b, i) in f.members}
        for j, a in enumerate(env.possible_agents):
            label = before[slots[a] - 1] if slots[a] else ""
            assert infos[a]["slot"] == slots[a] and infos[a]["track"] == label
            assert infos[a]["served"] == holder.get(label, "") == env.sim.agents[j].serves
            assert infos[a]["track_gone"] == (label != "" and label not in holder)
            regrouped |= infos[a]["served"] not in ("", label)
        moved |= infos["agent_0"]["slots"] != before
    assert moved and regrouped and len(predicted) == 8


def test_a_label_held_by_a_member_serves_its_cluster_and_a_gone_track_keeps_the_last_aim():
    sim = SwarmSimulation(two_targets("steps=3", "control.solver=exact", "fusion.share=scans"))
    first = sim.sure[0]
    oldest = track_label(first)
    other = next(f"a{g}:{b}.{i}" for g, (b, i) in first.members if f"a{g}:{b}.{i}" != oldest)
    aims = np.array([a.aim for a in sim.agents])
    r = sim.step((np.zeros(3, dtype=np.int64), np.array([3, 0, 0]), [other, "a9:9.9", ""]))
    assert r.step["mode"] == "external" and r.agents["serves"][0] == oldest  # found under its cluster's label
    assert list(r.agents["mode"]) == ["track", "hover", "hover"]
    np.testing.assert_array_equal(r.agents["point"][1:], aims[1:])  # gone and none: the last aims
    assert not np.allclose(r.agents["point"][0], aims[0])  # moved to the served track's prediction


def test_an_empty_or_vanished_slot_serves_nothing_and_the_info_says_so():
    env = two_env()
    env.reset(seed=1)
    env._slot_labels = [[labels[0], "a7:7.7"] for labels in env._slot_labels]  # a track that no prediction holds
    aims = np.array([a.aim for a in env.sim.agents])
    _, _, _, _, infos = env.step({"agent_0": [0, 1, 2], "agent_1": [0, 1, 4], "agent_2": [0, 1, 1]})
    assert infos["agent_0"]["track"] == "a7:7.7" and infos["agent_0"]["track_gone"] and infos["agent_0"]["served"] == ""
    assert infos["agent_1"]["track"] == "" and not infos["agent_1"]["track_gone"] and infos["agent_1"]["served"] == ""
    assert infos["agent_2"]["served"] and not infos["agent_2"]["track_gone"]
    points = env.sim.log.rows["agents"]["point_x"][-1]
    np.testing.assert_array_equal(points[:2], aims[:2, 0])


def test_reward_is_the_summed_xi_at_the_true_targets_less_the_penalty_recomputed_from_the_logs():
    env = two_env("control.constraints=false", "steps=6", jam_penalty=0.3)
    obs, infos = env.reset(seed=4)
    ant, at_least = env.sim.c.base.antenna, env.sim.c.base.plan.at_least
    rng = np.random.default_rng(1)
    checked_jam = checked_detect = False
    while env.agents:
        actions = {a: np.array([rng.integers(3), rng.integers(2, 4), rng.integers(3)]) for a in env.agents}
        obs, rew, _, _, infos = env.step(actions)
        ag, tg = env.sim.log.rows["agents"], env.sim.log.rows["targets"]
        pos = np.stack([ag["x"][-1], ag["y"][-1], ag["z"][-1]], axis=1)
        points = np.stack([ag[f"point_{c}"][-1] for c in "xyz"], axis=1)
        level_w = ant.levels_w[[actions[a][1] for a in env.possible_agents]]
        truth = np.stack([tg[f"truth_{c}"][-1] for c in "xyz"], axis=1)
        xi = []
        for k, detectable in enumerate(tg["detectable"][-1]):
            p = detection_probability(truth[k], pos, points, level_w, ant) if detectable else np.zeros(3)
            xi.append(xi_by_subsets(p, at_least))
            checked_detect |= bool(np.max(p) > 0)
        R = interference_matrix(pos, points, level_w, ant).sum(axis=1)
        v = np.where(R >= ant.delta_w, 1 + np.log10(np.maximum(R, 1e-300) / ant.delta_w), 0.0)
        assert rew["agent_0"] == pytest.approx(sum(xi) - 0.3 * v.sum(), abs=1e-12)
        assert len(set(rew.values())) == 1
        assert infos["agent_1"]["xi_targets"].tolist() == pytest.approx(xi, abs=1e-12)
        assert [infos[a]["violation"] for a in env.possible_agents] == pytest.approx(v.tolist(), abs=1e-12)
        checked_jam |= bool(v.sum() > 0)
    assert checked_jam and checked_detect


def test_the_action_mask_is_the_moves_inside_every_level_and_none_or_an_occupied_slot():
    env = two_env("agents.initial=[[0.5, 50, 50], [20, 10, 10], [60, 50, 50]]", "steps=4")
    obs, infos = env.reset(seed=1)
    b = env.sim.c.base
    D, L = b.displacements, len(b.antenna.levels_w)
    rng = np.random.default_rng(3)
    some_masked = False
    while env.agents:
        masks = {a: infos[a]["action_mask"] for a in env.agents}
        positions = env.sim.positions.copy()
        for j, a in enumerate(env.agents):
            m = masks[a]
            assert m.dtype == bool and m.shape == (len(D) + L + 5,) and m[len(D): len(D) + L].all()
            inside = np.all((positions[j] + D >= b.low - 1e-9) & (positions[j] + D <= b.high + 1e-9), axis=1)
            np.testing.assert_array_equal(m[: len(D)], inside)
            occupied = dict(zip(swarm_observation_layout(3, 4), obs[a]))
            np.testing.assert_array_equal(m[len(D) + L:], [True] + [occupied[f"track{s}.occupied"] == 1 for s in
                                                                  range(1, 5)])
            some_masked |= not m[: len(D)].all()
        actions = {a: np.array([rng.integers(len(D)), 0, rng.integers(5)]) for a in env.agents}
        obs, _, _, _, infos = env.step(actions)
        for a in env.possible_agents:
            move, slot = int(actions[a][0]), int(actions[a][2])
            assert infos[a]["hovered"] == (not masks[a][move])
            if not masks[a][len(D) + L + slot]:  # an empty slot serves nothing
                assert infos[a]["served"] == "" and infos[a]["track"] == ""
    assert some_masked


@pytest.mark.parametrize("bad", [[79, 0, 0], [-1, 0, 0], [0, 4, 0], [0, 0, 5], [0, 0, -1], [0, 1], [0.5, 1, 1],
                                 [1, 2, 3, 4], "hover", [True, 0, 0], [[0], [1, 2], 3]])
def test_an_action_outside_the_space_names_the_agent_and_the_value(bad):
    env = two_env()
    env.reset(seed=1)
    actions = {a: np.array([0, 0, 0]) for a in env.agents}
    actions["agent_1"] = bad
    with pytest.raises(ValueError, match=r"^agent_1: action .* is outside the action space MultiDiscrete\(\[79, 4, 5\]\) "
                                         r"\(\[move, level, track slot\] indices\)"):
        env.step(actions)
    assert env.sim.t == 0  # nothing happened


def test_the_engine_refuses_bad_given_actions_before_the_step():
    sim = SwarmSimulation(two_targets("steps=2"))
    for bad, words in [(([0, 0, 0], [0, 0, 0]), "a triple"), (([0, 0, 0], [0, 0, 0], ["", 5, ""]), "serves must be 3"),
                       (([0, 0, 0], [0, 9, 0], ["", "", ""]), r"levels\[1\] = 9"),
                       (([0, 0], [0, 0, 0], ["", "", ""]), "moves must be 3")]:
        with pytest.raises(ValueError, match=f"^actions: .*{words}"):
            sim.step(bad)
    assert sim.t == 0 and sim.broken is None


@pytest.mark.parametrize("solver", ["greedy", "grasp", "exact"])
def test_a_solver_policy_through_the_env_is_the_run_simulate_gives(solver):
    base = SWARM + ["control.grasp.samples=200", "control.grasp.iterations=2", "control.grasp.threads=1"]
    env = parallel_env(load_scenario("swarm-3", base))  # the preset's solver is exact
    policy = solver_policy(env, solver)
    obs, _ = env.reset(seed=7)
    while env.agents:
        obs, _, _, _, infos = env.step(policy(obs))
    mine = env.sim.result()
    ref = simulate(load_scenario("swarm-3", base + [f"control.solver={solver}", "seed=7"]))
    for name, table in ref.tables.items():
        assert set(mine.tables[name]) == set(table), name
        for k in set(table) - TIMING:
            a, b = mine.tables[name][k], table[k]
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), (name, k)
    assert [infos[a]["served"] for a in env.possible_agents] == list(ref.agents["serves"][-5:])
    assert [infos[a]["level"] for a in env.possible_agents] == list(ref.agents["level_index"][-5:])
    assert (mine.steps["mode"] != "external").all()


def test_a_solver_the_swarm_does_not_have_is_refused():
    env = two_env()
    with pytest.raises(ValueError, match="^solver_policy: unknown solver 'astar'"):
        solver_policy(env, "astar")
    env.reset(seed=1)
    with pytest.raises(ValueError, match="whole team"):
        env.step({"agent_0": Planned("exact"), "agent_1": [0, 0, 0], "agent_2": [0, 0, 0]})
    assert env.sim.t == 0


def test_rollout_and_the_random_policy_on_several_targets():
    env = two_env(jam_penalty=0.5)
    rows = rollout(env, random_policy(env), [3, 4])
    again = rollout(env, random_policy(env, seed=9), [3, 4])
    assert [r["return"] for r in rows] == [r["return"] for r in again]
    assert rows[0]["steps"] == 5 and "truncated" in rows[0]["end"] and rows[0]["n_targets"] == 2
    for r in rows:
        assert r["return"] == pytest.approx(r["xi"] - r["penalty"], abs=1e-9)
    [exact] = rollout(env, solver_policy(env, "exact"), [3])
    assert exact["policy"] == "exact" and 0 < exact["xi"] <= 2 * exact["steps"]


@pytest.mark.filterwarnings("ignore:Environment's (minimum|maximum) state space value is")  # the truth is unbounded
def test_the_global_state_is_the_team_and_every_true_target():
    from pettingzoo.test.state_test import state_test
    from pettingzoo.utils.conversions import parallel_to_aec

    env = two_env("targets=[{id: a, initial: [20, 20, 20, 1.5, 2.0, 1.7]}, "
                  "{id: b, initial: [60, 60, 60, -1, 0, 0], appears: 3}]")
    with pytest.raises(RuntimeError, match="state\\(\\) before reset"):
        env.state()
    obs, _ = env.reset(seed=3)
    names = swarm_state_layout(3, 2)
    policy = random_policy(env, 1)
    absent = 0
    while env.agents:
        actions = policy(obs)
        obs, _, _, _, _ = env.step(actions)
        s = dict(zip(names, env.state()))
        assert env.state_space.contains(env.state())
        truth = env.sim.truth
        tg = env.sim.log.rows["targets"]
        for i in range(2):
            assert s[f"target{i}.exists"] == truth.exists[i] and s[f"target{i}.detectable"] == truth.detectable[i]
            assert s[f"target{i}.held"] == tg["held"][-1][i]
            expected = truth.states[i] if truth.exists[i] else np.zeros(6)
            np.testing.assert_allclose([s[f"target{i}.{v}"] for v in ("x", "y", "z", "vx", "vy", "vz")], expected,
                                       rtol=1e-6)
            absent += not truth.exists[i]
        for k in range(3):
            np.testing.assert_allclose([s[f"agent{k}.{c}"] for c in "xyz"], env.sim.positions[k], atol=1e-5)
            assert s[f"agent{k}.level"] == actions[f"agent_{k}"][1]
        assert s["time"] == pytest.approx(env.sim.t / 5)
    assert absent == 2  # target b appears at step 3: absent on steps 1 and 2
    state_test(parallel_to_aec(two_env()), two_env())


def test_render_replay_writes_the_several_target_replay(tmp_path):
    # render_mode="replay" had been refused at construction: the swarm engine wrote no replay
    path = tmp_path / "episode.html"
    env = two_env("steps=3", render_mode="replay", replay_path=str(path))
    env.reset(seed=1)
    with pytest.raises(RuntimeError, match="before the first step"):
        env.render()
    env.step({a: np.array([0, 3, 1]) for a in env.agents})
    assert env.render() == path and path.is_file()
    page = path.read_text()
    assert page.count('"name":"target a"') == 2 and page.count('"name":"target b"') == 2  # the data, one frame
    env.step({a: np.array([1, 2, 1]) for a in env.agents})
    env.render()
    page = path.read_text()
    assert page.count('"name":"target a"') == 3  # rewritten: now two frames
    assert "(solver external)" in page[: page.index("</title>")]
    assert [p.name for p in tmp_path.iterdir()] == ["episode.html"]  # written in place, no leftover
    with pytest.raises(ValueError, match=r"^replay_path: .* is a folder"):
        two_env(render_mode="replay", replay_path=str(tmp_path))


def test_render_draws_the_swarm_figure(monkeypatch):
    env = two_env("steps=2", render_mode="rgb_array")
    env.reset(seed=1)
    with pytest.raises(RuntimeError, match="before the first step"):
        env.render()
    env.step({a: np.array([0, 3, 1]) for a in env.agents})
    from trackjam.viz import swarm

    titles = []
    real = swarm.plot_swarm
    monkeypatch.setattr(swarm, "plot_swarm", lambda tables, fs, path: titles.append(fs.solver) or real(tables, fs, path))
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and img.shape[0] > 300
    assert img.min() < 100 and img.max() == 255
    env.step({a: Planned("greedy") for a in env.agents})
    env.render()
    assert titles == ["external", "greedy and external"]
    env.close()
    with pytest.raises(RuntimeError, match="after close"):
        env.render()


def test_the_episode_terminates_once_every_target_has_left_the_area():
    env = two_env("targets=[{id: a, initial: [99, 50, 50, 4, 0, 0], walls: leave}, "
                  "{id: b, initial: [99, 20, 20, 4, 0, 0], walls: leave}]")
    env.reset(seed=1)
    _, _, term, trunc, _ = env.step({a: np.array([0, 0, 0]) for a in env.agents})  # both appear at x = 99
    assert not any(term.values()) and not any(trunc.values())
    _, _, term, trunc, info = env.step({a: np.array([0, 0, 0]) for a in env.agents})
    assert term == dict.fromkeys(env.possible_agents, True) and not any(trunc.values())
    assert info["agent_2"]["end"] == "every target downed or gone by step 2" and env.agents == []
    with pytest.raises(RuntimeError, match="every target downed or gone by step 2.*call reset"):
        env.step({a: np.array([0, 0, 0]) for a in env.possible_agents})


def test_a_pickled_environment_goes_on_as_the_original_does():
    # mid-episode, e.g. to hand it to a worker process: the copy holds the slots and the streams
    import pickle

    env = two_env()
    env.reset(seed=2)
    env.step({a: np.array([0, 1, 1]) for a in env.agents})
    copy = pickle.loads(pickle.dumps(env))
    actions = {a: np.array([1, 2, 2]) for a in env.agents}
    a, b = env.step(actions), copy.step(actions)
    assert all(np.array_equal(a[0][k], b[0][k]) for k in a[0]) and a[1] == b[1]
    assert [i["served"] for i in a[4].values()] == [i["served"] for i in b[4].values()]
