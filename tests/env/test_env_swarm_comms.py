"""The several-target environment under the ``comms`` faults: each agent observes its own
fused view and what it last heard of its teammates, its slots name the labels of its own
observation, a broken agent stays in the episode with its action ignored; PettingZoo's API and
seed tests and one episode per seed under loss; without faults every agent sees the team's view."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from trackjam.config import load_scenario
from trackjam.env import parallel_env, solver_policy, swarm_observation_layout
from trackjam.simulation.swarm import confirmed, track_label

from swarm_scenarios import two_targets
from test_env_swarm import SWARM, episode

MATES = {0: (1, 2), 1: (0, 2), 2: (0, 1)}  # agent j's mate blocks 1, 2 hold these teammates


def two_env(*extra, **kw):
    return parallel_env(two_targets("steps=5", "control.solver=exact", *extra), **kw)


def named(obs, n=3):
    names = swarm_observation_layout(n, 4)
    return {a: dict(zip(names, o.tolist())) for a, o in obs.items()}


def mate(o, slot):
    return o[f"mate{slot}.received"], np.array([o[f"mate{slot}.{c}"] for c in "xyz"]), o[f"mate{slot}.age"]


def slot_labels(o, view):
    """The labels of a view's confirmed tracks the observation's slots show, checked against it."""
    labels = []
    for s in range(1, 5):
        if s <= len(view):
            f = view[s - 1]
            assert o[f"track{s}.occupied"] == 1
            np.testing.assert_allclose([o[f"track{s}.{v}"] for v in ("x", "y", "z", "vx", "vy", "vz")],
                                       f.estimate.mean, rtol=1e-5, atol=1e-4)
            assert o[f"track{s}.e"] == pytest.approx(f.estimate.existence, rel=1e-6)
            labels.append(track_label(f))
        else:
            assert not any(v for k, v in o.items() if k.startswith(f"track{s}."))
    return labels


@pytest.mark.parametrize("make", [lambda: two_env("comms.loss=0.3"),
                                  lambda: parallel_env(load_scenario("swarm-3", SWARM + ["comms.loss=0.3"]))],
                         ids=["two-targets", "swarm-3"])
def test_passes_the_pettingzoo_parallel_api_and_seed_tests_under_loss(make):
    env = make()
    assert env.sim.distributed
    parallel_api_test(env, num_cycles=5)
    parallel_seed_test(make, num_cycles=5)


def test_under_loss_the_same_seed_gives_the_same_episode_and_the_agents_see_apart():
    make = lambda: two_env("comms.loss=0.4", "steps=8")  # noqa: E731
    a_obs, a_rew, a_info = episode(make(), seed=5, policy_seed=2)
    b_obs, b_rew, b_info = episode(make(), seed=5, policy_seed=2)
    assert len(a_obs) == 9 and a_rew == b_rew
    for x, y in zip(a_obs, b_obs):
        assert all(np.array_equal(x[agent], y[agent]) for agent in x)
    for x, y in zip(a_info, b_info):
        assert all(x[agent]["slots"] == y[agent]["slots"] for agent in x)
    # the loss made the agents' slots differ on some step, and some teammate unheard
    assert any(len({tuple(i[a]["slots"]) for a in i}) > 1 for i in a_info[1:])
    assert any(v == 0 for o in a_obs[1:] for x in named(o).values() for k, v in x.items() if k.endswith(".received"))
    c_obs, _, _ = episode(make(), seed=6, policy_seed=2)
    assert not all(np.array_equal(x["agent_0"], y["agent_0"]) for x, y in zip(a_obs[1:], c_obs[1:]))


def test_with_every_message_lost_each_agent_sees_its_own_tracks_and_its_teammates_where_they_started():
    env = two_env("comms.loss=1")
    obs, infos = env.reset(seed=2)
    sim = env.sim
    start = sim.positions.copy()
    for j, a in enumerate(env.possible_agents):  # the cue's tracks, as its own filter holds them
        own = {f"a{j}:{b}.{i}": e for e in sim.agents[j].filter.estimates() for b, i in [e.label]}
        shown = [s for s in infos[a]["slots"] if s]
        assert len(shown) == 2 and set(shown) == set(own) and infos[a]["slots"][2:] == ["", ""]
        for s, label in enumerate(shown, start=1):
            np.testing.assert_allclose([named(obs)[a][f"track{s}.{v}"] for v in ("x", "y", "z")], own[label].mean[:3],
                                       rtol=1e-5)
        for slot, k in enumerate(MATES[j], start=1):  # the briefing: where the team starts
            received, u, age = mate(named(obs)[a], slot)
            assert received == 1 and age == 0 and np.allclose(u, start[k])
    rng = np.random.default_rng(1)
    while env.agents:
        actions = {a: np.array([rng.integers(20), 2, rng.integers(3)]) for a in env.agents}
        obs, _, _, _, infos = env.step(actions)
        assert not np.allclose(sim.positions, start)  # they moved: a teammate's position is not what it was
        for j, a in enumerate(env.possible_agents):
            o = named(obs)[a]
            view = confirmed(sim.views[j])
            assert all(g == j for f in view for g, _ in f.members)  # its own tracks only
            labels = slot_labels(o, view)
            assert infos[a]["slots"] == labels + [""] * (4 - len(labels))
            for s, f in enumerate(view[:4], start=1):  # no message says what the others served
                served = sim.agents[j].serves in {f"a{g}:{b}.{i}" for g, (b, i) in f.members}
                assert o[f"track{s}.served"] == served and o[f"track{s}.servers"] == pytest.approx(served / 3)
            for slot, k in enumerate(MATES[j], start=1):
                received, u, age = mate(o, slot)
                assert received == 0 and np.allclose(u, start[k]) and age == pytest.approx(sim.t / 5)
        assert len({tuple(i["slots"]) for i in infos.values()}) == 3


def test_an_action_serves_the_label_its_own_agent_saw_in_slot_1():
    env = two_env("comms.loss=1")
    _, infos = env.reset(seed=3)
    first = {a: infos[a]["slots"][0] for a in env.possible_agents}
    assert first["agent_0"] != first["agent_1"]  # two agents whose slot 1 holds different labels
    obs, _, _, _, infos = env.step({a: np.array([0, 2, 1]) for a in env.agents})
    for j, a in enumerate(env.possible_agents):
        assert infos[a]["slot"] == 1 and infos[a]["track"] == first[a]
        assert infos[a]["served"] and not infos[a]["track_gone"]
        assert infos[a]["served"] == env.sim.agents[j].serves and infos[a]["served"].startswith(f"a{j}:")
    # agent 0's label means nothing to agent 1, which heard nothing: one list for the team lost it
    sim = env.sim
    sim.reset()
    label = first["agent_0"]
    r = sim.step((np.zeros(3, dtype=np.int64), np.full(3, 2), [label] * 3))
    assert list(r.agents["serves"]) == [label, "", ""] and list(r.agents["mode"]) == ["track", "hover", "hover"]


def test_a_slot_names_its_own_agents_label_and_the_solvers_choice_its_slot_under_loss():
    env = two_env("comms.loss=0.5", "steps=8")
    obs, infos = env.reset(seed=4)
    rng = np.random.default_rng(5)
    solver = solver_policy(env, "exact")
    predicted = []
    real = env.sim._given
    env.sim._given = lambda tracks, *a, **k: (predicted.append(tracks), real(tracks, *a, **k))[1]
    checked = planned = 0
    while env.agents:
        before = {a: infos[a]["slots"] for a in env.agents}
        if env.sim.t % 2:
            obs, _, _, _, infos = env.step(solver(obs))
            for a in env.possible_agents:  # the slot the solver's choice held, in this agent's slots
                served, slot = infos[a]["served"], infos[a]["slot"]
                assert slot == (before[a].index(served) + 1 if served in before[a] else 0)
                planned += slot > 0
            continue
        slots = {a: int(rng.integers(0, 1 + sum(1 for s in before[a] if s))) for a in env.agents}
        given = len(predicted)
        obs, _, _, _, infos = env.step({a: np.array([0, 2, slots[a]]) for a in env.agents})
        views = predicted[given:]  # each working agent's predicted view, in index order
        for j, a in enumerate(env.possible_agents):
            label = before[a][slots[a] - 1] if slots[a] else ""
            holder = {f"a{g}:{b}.{i}": track_label(f) for f in views[j] for g, (b, i) in f.members}
            assert infos[a]["track"] == label and infos[a]["served"] == holder.get(label, "")
            assert infos[a]["track_gone"] == (label != "" and label not in holder)
            checked += bool(label)
    assert checked > 3 and planned > 0


def test_a_broken_agent_stays_in_the_episode_its_action_ignored():
    env = two_env("comms.failures=[{agent: 1, step: 2, mode: breakdown}]",
                  "agents.initial=[[30, 30, 30], [0.5, 10, 10], [60, 50, 50]]")
    obs, _ = env.reset(seed=2)
    b = env.sim.c.base
    out = int(np.flatnonzero(b.displacements[:, 0] < -1)[0])  # out of the area for agent 1, at x = 0.5
    obs, _, _, _, infos = env.step({a: np.array([0, 2, 1]) for a in env.agents})
    assert infos["agent_1"]["mode"] == "track" and infos["agent_1"]["served"]
    heard = {j: env.sim.known[j][1] for j in (0, 2)}
    assert all(stamp == 1 for stamp, _ in heard.values())
    where = env.sim.positions[1].copy()
    for t in (2, 3):
        obs, _, _, _, infos = env.step({a: np.array([out if a == "agent_1" else 0, 3, 1]) for a in env.agents})
        assert env.agents == env.possible_agents
        i = infos["agent_1"]
        assert i["mode"] == "down" and i["level"] == 0 and i["served"] == "" and i["move"] == 0
        assert not i["hovered"] and not i["track_gone"] and i["slot"] == 1
        assert infos["agent_0"]["mode"] == "track" and infos["agent_0"]["hovered"] is False
        np.testing.assert_array_equal(env.sim.positions[1], where)
        o = named(obs)
        assert i["slots"] == [""] * 4 and not any(v for k, v in o["agent_1"].items() if k.startswith("track"))
        mask = i["action_mask"]
        assert mask[-5:].tolist() == [True, False, False, False, False]
        for slot in (1, 2):  # it hears nothing
            assert mate(o["agent_1"], slot)[0] == 0 and mate(o["agent_1"], slot)[2] == pytest.approx((t - 1) / 5)
        for j, a in ((0, "agent_0"), (2, "agent_2")):  # its teammates guard where it last announced it was
            received, u, age = mate(o[a], 1 if j == 0 else 2)  # agent 1's block
            assert received == 0 and np.allclose(u, heard[j][1]) and age == pytest.approx((t - 1) / 5)


def test_the_per_agent_path_with_every_message_delivered_sees_the_teams_tracks_and_no_other_serving():
    # a failure after the last step takes the per-agent path with nothing lost: the same run as
    # without faults, the same slots; what changes is what an agent is told, not what it sees
    late, bare = two_env("comms.failures=[{agent: 1, step: 99, mode: breakdown}]"), two_env()
    assert late.sim.distributed and not bare.sim.distributed
    obs_l, info_l = late.reset(seed=2)
    obs_b, info_b = bare.reset(seed=2)
    rng = np.random.default_rng(4)
    shared = 0
    while bare.agents:
        prev = bare.sim.positions.copy()
        actions = {a: np.array([rng.integers(20), 2, 1 if a != "agent_2" else rng.integers(3)]) for a in bare.agents}
        obs_l, rew_l, _, _, info_l = late.step(actions)
        obs_b, rew_b, _, _, info_b = bare.step(actions)
        assert rew_l == rew_b
        np.testing.assert_array_equal(late.sim.positions, bare.sim.positions)
        for j, a in enumerate(bare.possible_agents):
            assert info_l[a]["slots"] == info_b[a]["slots"] and info_l[a]["served"] == info_b[a]["served"]
            ol, ob = named(obs_l)[a], named(obs_b)[a]
            for s in range(1, 5):
                for v in ("occupied", "x", "y", "z", "vx", "vy", "vz", "e", "served"):
                    assert ol[f"track{s}.{v}"] == ob[f"track{s}.{v}"]
                # without faults the team's share; told nothing, the agent knows its own antenna only
                assert ol[f"track{s}.servers"] == pytest.approx(ol[f"track{s}.served"] / 3)
                shared += ob[f"track{s}.servers"] > ob[f"track{s}.served"] / 3
            for slot, k in enumerate(MATES[j], start=1):  # heard this step, where it announced itself: before the move
                assert mate(ol, slot)[0] == mate(ob, slot)[0] == 1 and mate(ol, slot)[2] == mate(ob, slot)[2] == 0
                np.testing.assert_allclose(mate(ol, slot)[1], prev[k], atol=1e-5)
                np.testing.assert_allclose(mate(ob, slot)[1], bare.sim.positions[k], atol=1e-5)
    assert shared > 0 and not np.allclose(prev, bare.sim.positions)


def test_under_a_step_of_delay_a_teammate_is_where_it_announced_itself_a_step_late():
    # a prediction sent at the start of step t - 1 (before that step's move) arrives at step t:
    # never received this step, one step old, where the teammate stood after step t - 2
    env = two_env("comms.delay_steps=1")
    env.reset(seed=1)
    history = [env.sim.positions.copy()]  # after each step; [0] the start
    rng = np.random.default_rng(2)
    while env.agents:
        obs, _, _, _, infos = env.step({a: np.array([rng.integers(1, 20), 2, 1]) for a in env.agents})
        history.append(env.sim.positions.copy())
        t = env.sim.t
        for j, a in enumerate(env.possible_agents):
            for slot, k in enumerate(MATES[j], start=1):
                received, u, age = mate(named(obs)[a], slot)
                assert received == 0 and age == pytest.approx(1 / 5)
                np.testing.assert_allclose(u, history[max(t - 2, 0)][k], atol=1e-5)
    assert not np.allclose(history[-1], history[-3])
