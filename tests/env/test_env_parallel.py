"""The PettingZoo environment: the official API test, seeding, the hover rule, termination,
the reward against the logged geometry, rendering, and one clear error for every bad input."""


import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from trackjam.config import load_scenario
from trackjam.env import Planned, observation_layout, parallel_env, random_policy
from trackjam.radio.antenna import detection_probability, interference_matrix

from test_env_reward import xi_by_subsets

FAST = ["steps=6", "filter.particles=400", "filter.birth_particles=100", "control.solver=exact"]


def fast_env(*extra, **kw):
    return parallel_env(load_scenario("paper-fig3", FAST + list(extra)), **kw)


def run_random(env, seed, policy_seed):
    policy = random_policy(env, policy_seed)
    obs, _ = env.reset(seed=seed)
    seen, rewards = [obs], []
    while env.agents:
        obs, rew, _, _, _ = env.step(policy(obs))
        seen.append(obs)
        rewards.append(rew)
    return seen, rewards


def test_passes_the_pettingzoo_parallel_api_test():
    parallel_api_test(fast_env(), num_cycles=10)


def test_same_seed_and_actions_give_the_same_observations_and_rewards():
    a_obs, a_rew = run_random(fast_env(), seed=5, policy_seed=3)
    b_obs, b_rew = run_random(fast_env(), seed=5, policy_seed=3)
    assert len(a_obs) == 7
    for x, y in zip(a_obs, b_obs):
        for agent in x:
            assert np.array_equal(x[agent], y[agent])
    assert a_rew == b_rew
    c_obs, _ = run_random(fast_env(), seed=6, policy_seed=3)
    assert not np.array_equal(a_obs[-1]["agent_0"], c_obs[-1]["agent_0"])


def test_reset_without_a_seed_takes_the_scenarios_then_the_next():
    env = fast_env("seed=11")
    assert env.reset()[1]["agent_0"]["seed"] == 11
    assert env.reset()[1]["agent_0"]["seed"] == 12
    assert env.reset(seed=3)[1]["agent_0"]["seed"] == 3
    assert env.reset()[1]["agent_0"]["seed"] == 4


def test_spaces_and_layout():
    env = fast_env()
    n_moves, n_levels = len(env.sim.c.displacements), len(env.sim.c.antenna.levels_w)
    assert (n_moves, n_levels) == (79, 4)
    assert env.action_space("agent_2").nvec.tolist() == [79, 4]
    assert env.observation_space("agent_0").shape == (33,) == (len(observation_layout(3)),)
    # the dicts some wrappers read (an AttributeError before), the same objects as the methods give
    assert set(env.action_spaces) == set(env.observation_spaces) == set(env.possible_agents)
    assert all(env.action_spaces[a] is env.action_space(a) for a in env.possible_agents)
    assert all(env.observation_spaces[a] is env.observation_space(a) for a in env.possible_agents)


def test_observation_holds_position_own_estimate_and_what_teammates_announced():
    env = fast_env()
    obs, _ = env.reset(seed=2)
    assert np.all(obs["agent_1"][10::11][:2] == 0)  # nothing received before the first step
    prev = env.sim.team.positions
    obs, *_ = env.step({a: np.array([0, 1]) for a in env.agents})
    names = observation_layout(3)
    o = dict(zip(names, obs["agent_1"]))
    team = env.sim.team
    assert np.allclose([o["own.x"], o["own.y"], o["own.z"]], team.agents[1].position)
    own = team.agents[1].filter.estimate()
    assert o["own.est.e"] == pytest.approx(own.existence, rel=1e-6)
    assert np.allclose([o[f"own.est.{s}"] for s in ("x", "y", "z", "vx", "vy", "vz")], own.mean, rtol=1e-5)
    # agent 1's teammates, in index order: agents 0 and 2
    received = {m.sender: m for m in team.fresh(1)}
    for slot, k in ((1, 0), (2, 2)):
        assert o[f"mate{slot}.received"] == 1
        assert np.allclose([o[f"mate{slot}.{ax}"] for ax in "xyz"], prev[k])
        assert o[f"mate{slot}.pred.e"] == pytest.approx(received[k].estimate.existence, rel=1e-6)
    assert o["time"] == pytest.approx(1 / 6)
    for a in obs:
        assert env.observation_space(a).contains(obs[a])


def test_a_teammate_not_heard_from_is_flagged_and_zeroed():
    env = fast_env("comms.loss=1")
    env.reset(seed=2)
    obs, *_ = env.step({a: np.array([0, 1]) for a in env.agents})
    o = dict(zip(observation_layout(3), obs["agent_0"]))
    assert o["own.est.e"] > 0 and o["time"] > 0
    for slot in (1, 2):
        block = [v for k, v in o.items() if k.startswith(f"mate{slot}.")]
        assert len(block) == 11 and not any(block)


def test_a_broken_down_agent_keeps_its_place_and_says_so():
    env = fast_env("comms.failures=[{agent: 1, step: 1, mode: breakdown}]")
    env.reset(seed=2)
    before = env.sim.team.positions[1].copy()
    _, _, _, _, info = env.step({a: np.array([5, 3]) for a in env.agents})
    assert info["agent_1"]["mode"] == "down" and info["agent_0"]["mode"] == "external"
    assert np.allclose(env.sim.team.positions[1], before)


def test_a_move_out_of_the_area_hovers_and_says_so():
    env = fast_env("agents.initial=[[0.5,50,50],[20,10,10],[10,15,15]]")
    env.reset(seed=1)
    D = env.sim.c.displacements
    out = int(np.flatnonzero(D[:, 0] < -1)[0])
    inside = int(np.flatnonzero((D[:, 0] > 0) & (np.abs(D).max(axis=1) <= 1))[0])
    _, _, _, _, info = env.step({"agent_0": [out, 0], "agent_1": [inside, 0], "agent_2": [0, 0]})
    assert info["agent_0"]["hovered"] and info["agent_0"]["move"] == 0
    assert np.allclose(env.sim.team.agents[0].position, [0.5, 50, 50])
    assert not info["agent_1"]["hovered"] and info["agent_1"]["move"] == inside
    assert np.allclose(env.sim.team.agents[1].position, np.array([20, 10, 10]) + D[inside])


def test_an_agent_moving_along_a_wall_stays_inside_the_observation_space():
    # moves along a wall have components of -1e-16 across it: from x = 0 the engine (which admits
    # 1e-9 m past a wall) put the agent at x = -1.3e-16, and the observation left its Box
    env = fast_env("agents.initial=[[0,50,50],[20,10,10],[10,15,15]]")
    env.reset(seed=1)
    D = env.sim.c.displacements
    along = int(np.flatnonzero((D[:, 0] < 0) & (D[:, 0] > -1e-9))[0])
    obs, *_ = env.step({"agent_0": [along, 0], "agent_1": [0, 0], "agent_2": [0, 0]})
    assert env.sim.team.agents[0].position[0] < 0  # the engine's position, untouched
    assert obs["agent_0"][0] == 0.0
    assert all(env.observation_space(a).contains(obs[a]) for a in obs)


def test_reward_is_xi_at_the_truth_less_the_penalty_recomputed_from_the_geometry():
    env = fast_env("antenna.pointing=aim", "control.constraints=false", jam_penalty=0.3)
    env.reset(seed=4)
    s, ant = env.scenario, env.sim.c.antenna
    rng = np.random.default_rng(0)
    checked_jam = checked_detect = False
    while env.agents:
        actions = {a: np.array([rng.integers(3), rng.integers(2, 4)]) for a in env.agents}
        _, rew, _, _, info = env.step(actions)
        r = env.sim.log.steps[-1]
        truth = np.array([r["truth_x"], r["truth_y"], r["truth_z"]])
        pos = env.sim.team.positions
        points = env.sim.team.aims
        level_w = ant.levels_w[[actions[a][1] for a in env.possible_agents]]
        p = detection_probability(truth, pos, points, level_w, ant) if r["target_detectable"] else np.zeros(3)
        R = interference_matrix(pos, points, level_w, ant).sum(axis=1)
        v = np.where(R >= ant.delta_w, 1 + np.log10(np.maximum(R, 1e-300) / ant.delta_w), 0.0)
        expected = xi_by_subsets(p, s.control.at_least) - 0.3 * v.sum()
        assert rew["agent_0"] == pytest.approx(expected, abs=1e-12)
        assert rew["agent_0"] == rew["agent_1"] == rew["agent_2"]
        assert [info[a]["violation"] for a in env.possible_agents] == pytest.approx(v.tolist(), abs=1e-12)
        assert info["agent_2"]["xi"] == pytest.approx(xi_by_subsets(p, s.control.at_least), abs=1e-12)
        checked_jam |= bool(v.sum() > 0)
        checked_detect |= bool(p.max() > 0)
    assert checked_jam and checked_detect


def test_episode_terminates_when_the_target_is_downed():
    env = fast_env("steps=20", "target.response={threshold_db: -60, steps: 2, action: land}")
    env.reset(seed=1)
    ended = None
    for _ in range(20):
        _, _, term, trunc, info = env.step({a: Planned("exact") for a in env.agents})
        if term["agent_0"]:
            ended = info["agent_0"]["end"]
            break
    assert ended is not None and "downed" in ended
    assert not trunc["agent_0"] and env.agents == []
    assert f"step {env.sim.truth.downed_at}" in ended


def test_episode_terminates_when_the_target_leaves_the_area():
    env = fast_env("target.walls=leave", "target.initial=[99,50,50,4,0,0]")
    env.reset(seed=1)
    _, _, term, _, _ = env.step({a: np.array([0, 0]) for a in env.agents})  # appears at x = 99
    assert not any(term.values())
    _, _, term, trunc, info = env.step({a: np.array([0, 0]) for a in env.agents})
    assert term == dict.fromkeys(env.possible_agents, True)
    assert not any(trunc.values()) and "left the area by step 2" in info["agent_1"]["end"]


def test_truncation_at_steps():
    env = fast_env()
    env.reset(seed=1)
    for t in range(6):
        _, _, term, trunc, _ = env.step({a: np.array([0, 0]) for a in env.agents})
        assert not any(term.values())
        assert all(trunc.values()) == (t == 5)
    assert env.agents == []


@pytest.mark.parametrize("bad", [[79, 0], [-1, 0], [0, 4], [0.5, 1], [1, 2, 3], "hover"])
def test_an_action_outside_the_space_names_the_agent_and_the_value(bad):
    env = fast_env()
    env.reset(seed=1)
    actions = {a: np.array([0, 0]) for a in env.agents}
    actions["agent_2"] = bad
    with pytest.raises(ValueError, match=r"agent_2: action .*" + str(bad)[:3].replace("[", r"\[")):
        env.step(actions)
    assert env.sim.t == 0  # nothing happened


def test_a_wrong_agent_name_is_named():
    env = fast_env()
    env.reset(seed=1)
    actions = {a: np.array([0, 0]) for a in env.agents} | {"agent_7": np.array([0, 0])}
    with pytest.raises(ValueError, match="unknown agent 'agent_7'"):
        env.step(actions)
    with pytest.raises(ValueError, match="unknown agent 'pilot'"):
        env.action_space("pilot")


def test_a_missing_agent_is_named():
    env = fast_env()
    env.reset(seed=1)
    with pytest.raises(ValueError, match="no action for agent_1"):
        env.step({"agent_0": np.array([0, 0]), "agent_2": np.array([0, 0])})


def test_step_after_the_end_is_refused_until_reset():
    env = fast_env("steps=1")
    env.reset(seed=1)
    env.step({a: np.array([0, 0]) for a in env.agents})
    with pytest.raises(RuntimeError, match="truncated after 1 steps.*call reset"):
        env.step({a: np.array([0, 0]) for a in env.possible_agents})
    env.reset(seed=1)
    env.step({a: np.array([0, 0]) for a in env.agents})


def test_bad_keyword_arguments_are_named():
    with pytest.raises(ValueError, match="jam_penalty"):
        fast_env(jam_penalty=-1)
    with pytest.raises(ValueError, match="render_mode"):
        fast_env(render_mode="human")
    env = fast_env()
    with pytest.raises(ValueError, match="seed=-2"):
        env.reset(seed=-2)
    env.reset(seed=1)
    with pytest.raises(ValueError, match="whole team"):
        env.step({"agent_0": Planned("exact"), "agent_1": [0, 0], "agent_2": [0, 0]})
    with pytest.raises(ValueError, match="unknown solver 'astar'"):
        env.step({a: Planned("astar") for a in env.agents})


def test_render_gives_the_figure_as_pixels_and_writes_the_replay(tmp_path):
    env = fast_env("steps=2", render_mode="rgb_array")
    env.reset(seed=1)
    with pytest.raises(RuntimeError, match="before the first step"):
        env.render()
    env.step({a: np.array([0, 3]) for a in env.agents})
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and img.shape[0] > 500
    assert img.min() < 100 and img.max() == 255  # something is drawn on a white page
    env = fast_env("steps=2", render_mode="replay", replay_path=str(tmp_path / "r.html"))
    env.reset(seed=1)
    env.step({a: np.array([0, 3]) for a in env.agents})
    path = env.render()
    assert path.read_text().count("trackjam-replay") >= 1
    assert [p.name for p in tmp_path.iterdir()] == ["r.html"]


@pytest.mark.parametrize("n", [0, -1, True, 2.0, "3", None, 65, 10**5])
def test_observation_layout_refuses_what_is_not_a_team_size(n):
    with pytest.raises(ValueError, match=r"^n_agents: expected a whole number in \[1, 64\]"):
        observation_layout(n)
    assert len(observation_layout(np.int64(1))) == 11  # one agent: its own entries and the time
    assert len(observation_layout(64)) == 11 * 64  # the largest team a scenario may have


def test_the_action_mask_is_the_moves_that_stay_inside_and_every_level():
    # agent 0 stands 0.5 m from the wall x = 0: every move with dx < -0.5 is masked, and a masked
    # move is exactly one the step turns into hovering
    env = fast_env("agents.initial=[[0.5,50,50],[20,10,10],[10,15,15]]")
    _, infos = env.reset(seed=1)
    D, L = env.sim.c.displacements, len(env.sim.c.antenna.levels_w)
    mask = infos["agent_0"]["action_mask"]
    assert mask.dtype == bool and mask.shape == (len(D) + L,) and mask[len(D):].all()
    np.testing.assert_array_equal(mask[: len(D)], 0.5 + D[:, 0] >= -1e-9)  # in_area's tolerance
    assert 0 < mask[: len(D)].sum() < len(D) and infos["agent_1"]["action_mask"][: len(D)].all()
    rng = np.random.default_rng(0)
    policy = random_policy(env, 4)
    obs = None
    while env.agents:
        masks = {a: infos[a]["action_mask"] for a in env.agents}
        actions = policy(obs)
        actions["agent_0"] = np.array([rng.integers(len(D)), 0])  # often out of the area near the wall
        positions = env.sim.team.positions.copy()
        obs, _, _, _, infos = env.step(actions)
        for a, j in zip(("agent_0", "agent_1", "agent_2"), range(3)):
            move = int(np.asarray(actions[a])[0])
            assert infos[a]["hovered"] == (not masks[a][move])
            inside = np.all((positions[j] + D >= env.sim.c.low - 1e-9) & (positions[j] + D <= env.sim.c.high + 1e-9), axis=1)
            np.testing.assert_array_equal(masks[a][: len(D)], inside)


@pytest.mark.filterwarnings("ignore:Environment's (minimum|maximum) state space value is")  # estimates are unbounded
def test_the_global_state_is_the_team_and_the_truth_and_passes_pettingzoo_state_test():
    from pettingzoo.test.state_test import state_test
    from pettingzoo.utils.conversions import parallel_to_aec

    from trackjam.env import state_layout

    env = fast_env("steps=20", "target.occlusions=[[3, 4]]")
    with pytest.raises(RuntimeError, match="state\\(\\) before reset"):
        env.state()
    obs, _ = env.reset(seed=3)
    names = state_layout(3)
    assert len(names) == 39 == env.state_space.shape[0] and len(set(names)) == 39
    policy = random_policy(env, 1)
    hidden = 0
    while env.agents:
        obs, _, _, _, _ = env.step(policy(obs))
        s = dict(zip(names, env.state()))
        assert env.state_space.contains(env.state())
        truth = env.sim.truth
        assert s["target.exists"] == truth.exists and s["target.detectable"] == truth.detectable
        hidden += truth.exists and not truth.detectable
        np.testing.assert_allclose([s[f"target.{k}"] for k in ("x", "y", "z", "vx", "vy", "vz")], truth.state, rtol=1e-6)
        for k, agent in enumerate(env.sim.team.agents):
            np.testing.assert_allclose([s[f"agent{k}.{c}"] for c in "xyz"], agent.position, atol=1e-5)
            est = agent.filter.estimate()
            np.testing.assert_allclose(s[f"agent{k}.est.e"], est.existence, rtol=1e-6)
            np.testing.assert_allclose([s[f"agent{k}.est.{c}"] for c in ("x", "vz")], est.mean[[0, 5]], rtol=1e-5)
        assert s["time"] == pytest.approx(env.sim.t / 20)
    assert hidden == 2  # the occluded steps 3 and 4: present, not detectable
    state_test(parallel_to_aec(fast_env()), fast_env())
    env.close()
    with pytest.raises(RuntimeError, match="state\\(\\) after close"):
        env.state()
