"""The observation-normalising wrapper on both environments: PettingZoo's API test, the same
episode as the bare environment (the wrapped observations and state map back to its own up to
float32 rounding), each entry's scale read from its name and the scenario, the wrapped Boxes,
and one clear error for every bad argument."""

import pickle

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from trackjam.config import load_scenario
from trackjam.env import (
    NormalizedObservations,
    normalized,
    observation_layout,
    parallel_env,
    random_policy,
    state_layout,
    swarm_observation_layout,
    swarm_state_layout,
)

from swarm_scenarios import two_targets

ONE = ["steps=4", "filter.particles=200", "filter.birth_particles=50", "control.solver=greedy"]


def one_env(**kw):
    return parallel_env(load_scenario("paper-fig3", ONE), **kw)


def two_env(**kw):
    return parallel_env(two_targets("steps=4"), **kw)


def lossy_env(**kw):  # each agent on its own view: the teammates' received flags and ages
    return parallel_env(two_targets("steps=4", "comms.loss=0.5"), **kw)


MAKERS = pytest.mark.parametrize("make", [one_env, two_env, lossy_env], ids=["one-target", "two-targets", "lossy"])


def layouts(env):
    n = len(env.possible_agents)
    if hasattr(env, "track_slots"):
        return swarm_observation_layout(n, env.track_slots), swarm_state_layout(n, len(env.target_ids))
    return observation_layout(n), state_layout(n)


def area(env):
    c = env.sim.c.base if hasattr(env, "track_slots") else env.sim.c
    return c.low, c.high, float(np.linalg.norm(c.displacements, axis=1).max())


def expected(names, box, x, low, high, speed):
    """Each entry scaled by hand from its name: a bounded one from its Box onto [-1, 1], an
    unbounded position by the area, an unbounded velocity by ``speed``."""
    out = []
    for name, lo, hi, v in zip(names, box.low, box.high, x.astype(float)):
        axis = name.rsplit(".", 1)[-1]
        if np.isfinite(lo) and np.isfinite(hi):
            out.append(2 * (v - lo) / (hi - lo) - 1 if hi > lo else 0.0)
        elif axis in ("vx", "vy", "vz"):
            out.append(v / speed)
        else:
            k = "xyz".index(axis)
            out.append(2 * (v - low[k]) / (high[k] - low[k]) - 1)
    return np.array(out)


def tables(env):
    """The run's logs, column name -> array, per log."""
    res = env.sim.result()
    return res.tables if hasattr(res, "tables") else {"steps": res.steps, "agents": res.agents}


def close_in_float32(a, b, scale):
    """``a`` and ``b`` differ by no more than float32 rounding of values of size ``scale``."""
    return np.all(np.abs(np.asarray(a, float) - np.asarray(b, float)) <= 4 * np.finfo(np.float32).eps * scale)


@MAKERS
def test_passes_the_pettingzoo_parallel_api_and_seed_tests(make):
    env = normalized(make())
    assert isinstance(env, NormalizedObservations)
    parallel_api_test(env, num_cycles=5)
    parallel_seed_test(lambda: normalized(make()), num_cycles=5)


@MAKERS
def test_the_wrapped_episode_is_the_bare_one_and_maps_back(make):
    bare, wrapped = make(), normalized(make())
    obs_names, state_names = layouts(bare)
    low, high, top = area(bare)
    assert wrapped.speed == top  # the pursuers' top speed, m per step of 1 s
    raw, _ = bare.reset(seed=5)
    scaled, _ = wrapped.reset(seed=5)
    policy_a, policy_b = random_policy(bare, 3), random_policy(wrapped, 3)
    unbounded = 0
    while True:
        for a in bare.possible_agents:
            box = bare.observation_space(a)
            assert wrapped.observation_space(a).contains(scaled[a])
            want = expected(obs_names, box, raw[a], low, high, top)
            scale = np.maximum(np.abs(want), 1.0)
            assert close_in_float32(scaled[a], want, scale), a
            back = wrapped.unnormalize_observation(scaled[a])
            size = np.maximum(np.abs(raw[a]).astype(float), np.where(np.isfinite(box.high), box.high, high.max()))
            assert close_in_float32(back, raw[a], size), a
            finite = np.isfinite(box.low) & np.isfinite(box.high)
            assert np.all(np.abs(scaled[a][finite]) <= 1)
            unbounded += np.count_nonzero(raw[a][~finite])
        s_raw, s_scaled = bare.state(), wrapped.state()
        assert wrapped.state_space.contains(s_scaled)
        want = expected(state_names, bare.state_space, s_raw, low, high, top)
        assert close_in_float32(s_scaled, want, np.maximum(np.abs(want), 1.0))
        assert close_in_float32(wrapped.unnormalize_state(s_scaled), s_raw,
                                np.maximum(np.abs(s_raw).astype(float), high.max()))
        if not bare.agents:
            break
        acts_a, acts_b = policy_a(raw), policy_b(scaled)
        assert all(np.array_equal(acts_a[k], acts_b[k]) for k in acts_a)
        raw, rew_a, term_a, trunc_a, info_a = bare.step(acts_a)
        scaled, rew_b, term_b, trunc_b, info_b = wrapped.step(acts_b)
        assert rew_a == rew_b and term_a == term_b and trunc_a == trunc_b
        assert [i["level"] for i in info_a.values()] == [i["level"] for i in info_b.values()]
    assert unbounded > 0  # the estimates (scaled by the area and the speed) were checked, not only zeros
    for name, table in tables(bare).items():
        mine = tables(wrapped)[name]
        for k in set(table) - {"solve_s", "step_s"}:
            assert np.array_equal(mine[k], table[k], equal_nan=table[k].dtype.kind == "f"), (name, k)


@MAKERS
def test_the_wrapped_boxes_are_minus_one_to_one_where_the_environment_bounds_an_entry(make):
    env = make()
    wrapped = normalized(env)
    obs_names, state_names = layouts(env)
    for names, box, mine in [(obs_names, env.observation_space("agent_0"), wrapped.observation_space("agent_0")),
                             (state_names, env.state_space, wrapped.state_space)]:
        finite = np.isfinite(box.low) & np.isfinite(box.high)
        assert finite.any() and (~finite).any()
        assert np.all(mine.low[finite] == -1) and np.all(mine.high[finite] == 1)
        assert np.all(np.isinf(mine.low[~finite])) and np.all(np.isinf(mine.high[~finite]))
        assert all(n.rsplit(".", 1)[-1] in ("x", "y", "z", "vx", "vy", "vz") for n, f in zip(names, finite) if not f)
        assert mine.dtype == np.float32 and mine.shape == box.shape
    assert wrapped.observation_spaces["agent_1"] is wrapped.observation_space("agent_1")
    assert wrapped.action_space("agent_1") is env.action_space("agent_1")


def test_speed_scales_the_velocities_only():
    env = two_env()
    slow, fast = normalized(two_env(), speed=2), normalized(two_env(), speed=np.float32(8))
    names, _ = layouts(env)
    a, _ = slow.reset(seed=2)
    b, _ = fast.reset(seed=2)
    velocity = np.array([n.endswith((".vx", ".vy", ".vz")) for n in names])
    for k in a:
        assert np.any(a[k][velocity] != 0)
        assert close_in_float32(a[k][velocity], 4 * b[k][velocity], np.abs(a[k][velocity]).max())
        assert np.array_equal(a[k][~velocity], b[k][~velocity])


@MAKERS
def test_a_wrapped_environment_pickled_mid_episode_goes_on_as_the_original(make):
    env = normalized(make())
    obs, _ = env.reset(seed=4)
    policy = random_policy(env, 1)
    env.step(policy(obs))
    copy = pickle.loads(pickle.dumps(env))
    assert isinstance(copy, NormalizedObservations) and copy.speed == env.speed
    actions = policy(obs)
    a, b = env.step(actions), copy.step(actions)
    assert all(np.array_equal(a[0][k], b[0][k]) for k in a[0]) and a[1] == b[1]
    assert np.array_equal(env.state(), copy.state())


def test_the_speed_bound_is_the_configurations():
    from trackjam.config.limits import MAX_SPEED
    from trackjam.env import wrappers

    assert wrappers.MAX_SPEED == MAX_SPEED


@pytest.mark.parametrize("speed", [0, -1.0, float("nan"), float("inf"), 1001, "5", True, [5]])
def test_a_speed_that_is_not_a_bounded_number_is_named(speed):
    with pytest.raises(ValueError, match=r"^normalized: speed must be a number of m/s in \(0, 1000\], got "):
        normalized(two_env(), speed=speed)


def test_what_is_not_a_bare_environment_of_ours_is_refused():
    with pytest.raises(TypeError, match=r"^normalized: env must be an environment of trackjam\.env\.parallel_env, "
                                        r"got NoneType None"):
        normalized(None)
    with pytest.raises(TypeError, match=r"^normalized: env must be .*got str 'swarm-3'"):
        normalized("swarm-3")
    with pytest.raises(ValueError, match=r"^normalized: env is already normalized"):
        normalized(normalized(one_env()))


@MAKERS
def test_the_wrapper_passes_on_the_environments_refusals_and_steps_nothing(make):
    env = normalized(make())
    with pytest.raises(RuntimeError, match=r"state\(\) before reset"):
        env.state()
    with pytest.raises(RuntimeError, match=r"step\(\) before reset"):
        env.step({})
    with pytest.raises(ValueError, match=r"^unknown agent 'agent_9'"):
        env.observation_space("agent_9")
    env.reset(seed=1)
    n = len(env.action_space("agent_0").nvec)
    actions = {a: np.zeros(n, dtype=int) for a in env.agents}
    actions["agent_2"] = np.full(n, np.nan)
    with pytest.raises(ValueError, match=r"^agent_2: action \[nan, .*\] is outside the action space"):
        env.step(actions)
    assert env.sim.t == 0
    with pytest.raises(ValueError, match=r"^unnormalize_observation: expected a vector of \d+ entries, "
                                         r"got shape \(3,\)"):
        env.unnormalize_observation(np.zeros(3))
    with pytest.raises(ValueError, match=r"^normalize_state: expected a vector of \d+ entries, got shape \(\)"):
        env.normalize_state(1.0)


@MAKERS
def test_rollout_and_the_solver_policy_take_a_wrapped_environment_and_give_the_bare_ones_rows(make):
    from trackjam.env import rollout, solver_policy

    bare, wrapped = make(), normalized(make())
    for a, b in [(random_policy(bare, 2), random_policy(wrapped, 2)),
                 (solver_policy(bare, "greedy"), solver_policy(wrapped, "greedy"))]:
        mine, theirs = rollout(wrapped, b, [3]), rollout(bare, a, [3])
        assert [r["return"] for r in mine] == [r["return"] for r in theirs]
        assert [r["steps"] for r in mine] == [r["steps"] for r in theirs] == [4]


def test_a_teammates_received_flag_and_age_are_scaled_from_their_bounds_and_its_position_by_the_area():
    # under comms.loss 1 nothing is heard: received 0 reads -1, the age (t / steps) climbs from -1 to
    # 1 at the last step, the position (its start, the briefing) is scaled by the area as the agent's own
    env = normalized(parallel_env(two_targets("steps=4", "comms.loss=1")))
    names = swarm_observation_layout(3, env.track_slots)
    low, high, _ = area(env)
    start = env.sim.positions.copy()
    obs, _ = env.reset(seed=1)
    ages = []
    while env.agents:
        obs, *_ = env.step({a: np.array([1, 2, 0]) for a in env.agents})
        o = dict(zip(names, obs["agent_0"]))
        assert o["mate1.received"] == o["mate2.received"] == -1
        assert o["mate1.age"] == o["mate2.age"]
        ages.append(float(o["mate1.age"]))
        for slot, k in ((1, 1), (2, 2)):
            want = 2 * (start[k] - low) / (high - low) - 1
            np.testing.assert_allclose([o[f"mate{slot}.{c}"] for c in "xyz"], want, atol=1e-6)
    assert ages == pytest.approx([2 * t / 4 - 1 for t in range(1, 5)])  # age t / steps, [0, 1] onto [-1, 1]
    assert not np.allclose(env.sim.positions[1:], start[1:])  # they moved; the agent never heard it
