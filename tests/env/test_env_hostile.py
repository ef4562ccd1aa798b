"""The environment's constructor and reset against a hostile caller: one exception naming the
argument, at construction, instead of an AttributeError deep inside, a reward of -inf, or a
replay that fails to write after the episode."""

import numpy as np
import pytest

from trackjam.config import load_scenario
from trackjam.env import parallel_env
from trackjam.env.parallel import MAX_JAM_PENALTY

FAST = ["steps=3", "filter.particles=200", "filter.birth_particles=50", "control.solver=greedy"]


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper-fig3", FAST)


@pytest.mark.parametrize("bad", ["paper-fig3", None, {"steps": 3}])
def test_a_scenario_that_is_not_one_is_named(bad):
    with pytest.raises(TypeError, match=r"^scenario: expected a Scenario .*got (str|NoneType|dict)$"):
        parallel_env(bad)


@pytest.mark.parametrize("bad", ["1", None, True, [1], float("nan"), float("inf"), -1.0, 1e308])
def test_a_jam_penalty_that_is_not_a_bounded_number_is_named(scenario, bad):
    with pytest.raises(ValueError, match=r"^jam_penalty: must be a number in \[0, 1e\+06\]"):
        parallel_env(scenario, jam_penalty=bad)


def test_the_largest_penalty_keeps_the_reward_finite_where_1e308_made_it_minus_inf(scenario):
    env = parallel_env(scenario, jam_penalty=MAX_JAM_PENALTY)
    env.reset(seed=1)
    top = len(scenario.antenna.power_levels_db) - 1
    _, rewards, *_ = env.step({a: np.array([0, top]) for a in env.agents})  # every agent at full power
    assert all(np.isfinite(r) for r in rewards.values())


@pytest.mark.parametrize(
    "path, error, words",
    [
        (None, TypeError, "expected a file's path as text, got NoneType None"),
        (5, TypeError, "expected a file's path as text, got int 5"),
        (b"/tmp/r.html", TypeError, "expected a file's path as text, got bytes"),
        ("{tmp}/r\x00.html", ValueError, "holds a NUL character"),  # render() failed in tempfile
        ("", ValueError, "expected a file's path, got an empty text"),
        ("{tmp}", ValueError, "is a folder, not a file"),
        ("{tmp}/missing/replay.html", ValueError, "missing is not an existing folder"),
    ],
)
def test_a_replay_path_render_could_not_write_is_refused_at_construction(scenario, tmp_path, path, error, words):
    path = path.format(tmp=tmp_path) if isinstance(path, str) else path
    with pytest.raises(error, match=f"^replay_path: .*{words}"):
        parallel_env(scenario, render_mode="replay", replay_path=path)


def test_a_good_replay_path_is_written(scenario, tmp_path):
    env = parallel_env(scenario, render_mode="replay", replay_path=str(tmp_path / "r.html"))
    env.reset(seed=1)
    env.step({a: np.array([0, 1]) for a in env.agents})
    assert env.render() == tmp_path / "r.html" and (tmp_path / "r.html").stat().st_size > 0


@pytest.mark.parametrize("seed", [2**63, 2**64, np.uint64(2**63 + 5)])
def test_a_seed_past_the_scenarios_bound_is_refused(scenario, seed):
    env = parallel_env(scenario)
    with pytest.raises(ValueError, match=r"the seed must be an integer in \[0, 2\^63 - 1\]"):
        env.reset(seed=seed)
    env.reset(seed=2**63 - 1)


@pytest.mark.parametrize("seed", [1.5, "3", True, -1])
def test_a_seed_that_is_not_a_whole_number_is_refused_by_the_policies(scenario, seed):
    from trackjam.env import random_policy, rollout

    env = parallel_env(scenario)
    with pytest.raises(ValueError, match=r"^random_policy: seed .* must be an integer >= 0"):
        random_policy(env, seed)
    # rollout read int(1.5) == int(1.7) == 1: two seeds, one episode twice
    with pytest.raises(ValueError, match=r"^rollout: seed .* must be an integer >= 0"):
        rollout(env, random_policy(env, 0), [seed])


def test_rollout_takes_numpy_integers(scenario):
    from trackjam.env import random_policy, rollout

    env = parallel_env(scenario)
    rows = rollout(env, random_policy(env, 0), np.arange(2, 4))
    assert [r["seed"] for r in rows] == [2, 3]


def test_reset_without_a_seed_after_the_last_seed_wraps_to_zero(scenario):
    # it ran seed 2^63, past the scenario's bound, and the run it wrote could not be run again
    env = parallel_env(scenario)
    env.reset(seed=2**63 - 1)
    _, infos = env.reset()
    assert next(iter(infos.values()))["seed"] == 0 and env.sim.scenario.seed == 0


def test_rollout_checks_every_argument_before_the_first_episode(scenario, monkeypatch):
    from trackjam.env import random_policy, rollout

    env = parallel_env(scenario)
    episodes = []
    real = env.reset
    monkeypatch.setattr(env, "reset", lambda **kw: (episodes.append(kw), real(**kw))[1])
    policy = random_policy(env, 0)
    with pytest.raises(ValueError, match=r"^rollout: seed -1 must be an integer"):
        rollout(env, policy, [1, 2, -1])
    with pytest.raises(ValueError, match=r"^rollout: seed 9223372036854775808 must be an integer"):
        rollout(env, policy, [1, 2**63])
    with pytest.raises(TypeError, match=r"^rollout: policy must be callable"):
        rollout(env, 5, [1])
    with pytest.raises(TypeError, match=r"^rollout: progress must be callable"):
        rollout(env, policy, [1], progress=5)
    assert episodes == []  # no episode ran


def test_a_planned_action_names_a_solver_by_text():
    from trackjam.env.parallel import Planned

    with pytest.raises(TypeError, match=r"^Planned: solver must be a solver's name \(greedy, grasp, exact\), got list"):
        Planned(["exact"])


def test_the_policies_and_rollout_refuse_what_is_not_an_environment_of_ours():
    # None failed at the first step with an AttributeError; a list of solvers was "unhashable type"
    import trackjam
    from trackjam.env import parallel_env, random_policy, rollout, solver_policy

    for call in (lambda: random_policy(None), lambda: solver_policy(None, "greedy"),
                 lambda: rollout(None, lambda obs: {}, [1])):
        with pytest.raises(TypeError, match=r"^(random_policy|solver_policy|rollout): env must be trackjam\.env"):
            call()
    env = parallel_env(trackjam.load_scenario("paper-fig3", ["steps=1"]))
    with pytest.raises(ValueError, match=r"^solver_policy: unknown solver \['exact'\]"):
        solver_policy(env, ["exact"])
    assert callable(solver_policy(env, "exact")) and callable(random_policy(env))


def test_a_solver_the_scenario_would_refuse_is_refused_before_it_plans():
    # the scenario's GRASP settings were checked only under control.solver: grasp, so
    # solver_policy(env, "grasp") ran 9e9 operations a step on a scenario solved by exact
    import trackjam
    from trackjam.env import solver_policy
    from trackjam.env.parallel import Planned
    from trackjam.errors import ConfigError

    s = trackjam.load_scenario("paper-fig3", ["steps=2", "filter.particles=100", "filter.birth_particles=20"],
                               control__solver="exact", control__grasp__samples=10**6,
                               control__grasp__iterations=1000)
    env = parallel_env(s)
    obs, _ = env.reset(seed=1)
    words = r"^grasp: not a solver this scenario takes: scenario: control\.grasp\.samples: one step would take"
    with pytest.raises(ConfigError, match=words):
        solver_policy(env, "grasp")
    with pytest.raises(ConfigError, match=words):
        env.step({a: Planned("grasp") for a in env.agents})
    assert env.sim.t == 0
    env.step(solver_policy(env, "exact")(obs))
    assert env.sim.t == 1


def test_close_in_with_greedy_is_refused_as_the_configuration_refuses_it():
    import trackjam
    from trackjam.env import solver_policy
    from trackjam.errors import ConfigError

    s = trackjam.load_scenario("paper-fig3", ["steps=2", "filter.particles=100", "filter.birth_particles=20"],
                               control__solver="exact", control__close_in=0.05)
    env = parallel_env(s)
    obs, _ = env.reset(seed=1)
    with pytest.raises(ConfigError, match=r"^greedy: not a solver this scenario takes: scenario: control\.close_in"):
        solver_policy(env, "greedy")
    env.step(solver_policy(env, "grasp")(obs))  # grasp takes close_in
    assert env.sim.t == 1 and env.sim.c.plan.solver == "grasp"


@pytest.mark.parametrize("action", [[True, 1], [np.True_, 0], np.array([True, False])])
def test_a_boolean_action_index_is_refused_as_the_engine_refuses_it(scenario, action):
    # numpy read [True, 1] as the integers [1, 1] and the step moved agent_0 by move 1
    env = parallel_env(scenario)
    env.reset(seed=1)
    actions = {a: [0, 0] for a in env.agents}
    actions["agent_0"] = action
    with pytest.raises(ValueError, match=r"^agent_0: action \[.*\] is outside the action space"):
        env.step(actions)


def test_a_huge_action_is_named_by_its_shape_not_printed(scenario):
    env = parallel_env(scenario)
    env.reset(seed=1)
    actions = {a: [0, 0] for a in env.agents}
    actions["agent_1"] = np.zeros(10**6, dtype=np.int64)
    with pytest.raises(ValueError, match=r"^agent_1: action an array of shape \(1000000,\) is outside"):
        env.step(actions)


def test_the_one_target_environment_sends_several_targets_to_parallel_env():
    # the engine's message sent the user to SwarmSimulation; parallel_env now dispatches on the count
    from trackjam.env import SwarmParallelEnv, TrackjamParallelEnv
    from trackjam.errors import ConfigError

    s = load_scenario("swarm-3", ["steps=2", "filter.particles=100", "filter.birth_particles=20"])
    with pytest.raises(ConfigError, match=r"^TrackjamParallelEnv simulates one target; this scenario has 3 "
                                          r"\(targets\): trackjam\.env\.parallel_env\(scenario\) gives"):
        TrackjamParallelEnv(s)
    assert type(parallel_env(s)) is SwarmParallelEnv
    with pytest.raises(ConfigError, match=r"^SwarmParallelEnv runs the swarm engine, for several targets; "
                                          r"this scenario has one"):
        SwarmParallelEnv(load_scenario("paper-fig3", FAST))
    with pytest.raises(ValueError, match=r"^track_slots: 3 given for a scenario with one target"):
        parallel_env(load_scenario("paper-fig3", FAST), track_slots=3)


def _two_targets_env():
    from swarm_scenarios import two_targets

    return parallel_env(two_targets("steps=3"))


BOTH = pytest.mark.parametrize("make", [lambda: parallel_env(load_scenario("paper-fig3", FAST)), _two_targets_env],
                               ids=["one-target", "two-targets"])


@BOTH
@pytest.mark.parametrize("bad", [[[0], [1, 2]], [[0, 1], [2]]])
def test_a_ragged_action_names_the_agent_in_both_environments(make, bad):
    # the one-target environment passed numpy's "inhomogeneous shape" ValueError on, naming no agent
    env = make()
    env.reset(seed=1)
    n = len(env.action_space("agent_0").nvec)
    actions = {a: np.zeros(n, dtype=int) for a in env.agents}
    actions["agent_1"] = bad
    with pytest.raises(ValueError, match=r"^agent_1: action \[\[.*\]\] is outside the action space"):
        env.step(actions)
    assert env.sim.t == 0


@BOTH
@pytest.mark.parametrize("bad", [np.array([np.nan, 0, 0]), np.array([0.0, 1.0, 1.0]), np.array([0, -2, 1]),
                                 np.array([0, 0, 1], dtype=np.uint64) - np.uint64(2), None, {"move": 0}])
def test_a_float_nan_negative_or_shapeless_action_names_the_agent_and_steps_nothing(make, bad):
    env = make()
    env.reset(seed=1)
    n = len(env.action_space("agent_0").nvec)
    bad = bad[:n] if isinstance(bad, np.ndarray) else bad
    actions = {a: np.zeros(n, dtype=int) for a in env.agents}
    actions["agent_2"] = bad
    with pytest.raises(ValueError, match=r"^agent_2: action .* is outside the action space MultiDiscrete"):
        env.step(actions)
    assert env.sim.t == 0
    actions["agent_2"] = np.ones(n, dtype=np.int8)  # any integer dtype inside the space is an action
    env.step(actions)
    assert env.sim.t == 1


@BOTH
def test_a_planned_action_beside_another_names_the_agent_that_breaks_the_team_plan(make):
    from trackjam.env import Planned

    env = make()
    env.reset(seed=1)
    n = len(env.action_space("agent_0").nvec)
    mixed = {a: Planned("greedy") for a in env.agents}
    mixed["agent_1"] = [0] * n
    # it said "a solver plans for the whole team" without the agent or its action
    with pytest.raises(ValueError, match=rf"^agent_1: action \[{', '.join(['0'] * n)}\] is not "
                                         r"Planned\(solver='greedy'\), which another agent has: a solver plans for "
                                         r"the whole team"):
        env.step(mixed)
    mixed["agent_1"] = Planned("exact")
    with pytest.raises(ValueError, match=r"^agent_1: action Planned\(solver='exact'\) is not "
                                         r"Planned\(solver='greedy'\)"):
        env.step(mixed)
    assert env.sim.t == 0


@BOTH
@pytest.mark.parametrize("options", ["fast", 5, [("a", 1)]])
def test_reset_options_that_are_not_a_dict_are_named(make, options):
    # they were accepted silently, as a dict is (and not read)
    env = make()
    with pytest.raises(ValueError, match=r"^reset\(options=.*\): options must be a dict or None"):
        env.reset(seed=1, options=options)
    env.reset(seed=1, options={"anything": 1})
    assert env.sim.t == 0 and env.agents


def test_the_several_target_class_takes_no_slots_as_the_default_as_parallel_env_does():
    # parallel_env(track_slots=None) was the default while SwarmParallelEnv(track_slots=None) was refused
    from swarm_scenarios import two_targets

    from trackjam.env import SwarmParallelEnv
    from trackjam.simulation.swarm import MAX_AIMS

    env = SwarmParallelEnv(two_targets("steps=2"), track_slots=None)
    assert env.track_slots == MAX_AIMS == parallel_env(two_targets("steps=2")).track_slots
    with pytest.raises(ValueError, match=r"^actions: expected a dict \{agent: \[move, level, track slot\]\}, got list"):
        env.reset(seed=1) and env.step([[0, 0, 0]] * 3)
