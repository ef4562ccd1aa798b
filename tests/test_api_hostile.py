"""The Python API at run time against a hostile caller: ``Simulation.step((moves, levels))`` and
the learning environment's ``step``, ``reset`` and ``rollout`` with actions or seeds that are out
of range, negative, fractional, NaN, of the wrong shape or kind, for missing or extra agents.
Each raises one exception naming the argument, before the step changes anything (numpy read a
negative index from the end, truncated 0.7 to 0, let a move leave the area, or failed deep
inside with an IndexError after the truth had already moved)."""

import numpy as np
import pytest

import trackjam

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.env import parallel_env
from trackjam.env.policies import random_policy, rollout
from trackjam.simulation.engine import Simulation

FAST = ["steps=3", "filter.particles=100", "filter.birth_particles=20", "control.solver=greedy"]
N_MOVES, N_LEVELS = 79, 4  # paper-fig3: Eq. (3) with 3 radii x 8 x 8 directions, plus hover; off and 3 levels


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper-fig3", FAST)


def _state(sim):
    # the truth's random stream: a step that had begun would have drawn from it
    return sim.t, sim.truth.rng.bit_generator.state, sim.team.positions.copy()


@pytest.mark.parametrize(
    "actions, words",
    [
        (([-1, 0, 0], [0, 0, 0]), r"moves\[0\] = -1 is not an index in \[0, 78\]"),
        (([0, 0, 0], [0, -1, 0]), r"levels\[1\] = -1 is not an index in \[0, 3\]"),
        (([0, 0, N_MOVES], [0, 0, 0]), r"moves\[2\] = 79 is not an index in \[0, 78\]"),
        (([0, 0, 0], [0, 0, N_LEVELS]), r"levels\[2\] = 4 is not an index in \[0, 3\]"),
        (([0, 0, 0], np.array([0, 0, 2**64 - 1], dtype=np.uint64)), r"levels\[2\] = 18446744073709551615"),
        (([0.7, 0, 0], [0, 0, 0]), "moves must be 3 integers"),
        (([0, 0, 0], [1.0, 0, 0]), "levels must be 3 integers"),
        (([np.nan, 0, 0], [0, 0, 0]), "moves must be 3 integers"),
        (([True, False, False], [0, 0, 0]), "moves must be 3 integers"),
        (([True, 0, 0], [0, 0, 0]), "moves must be 3 integers"),  # numpy read it as [1, 0, 0]
        (([0, 0, 0], [1, np.bool_(True), 0]), "levels must be 3 integers"),
        (([np.array(True), 0, 0], [0, 0, 0]), "moves must be 3 integers"),
        (([None, 0, 0], [0, 0, 0]), "moves must be 3 integers"),
        (([2**63, 0, 0], [0, 0, 0]), "moves must be 3 integers"),
        (("abc", [0, 0, 0]), "moves must be 3 integers"),
        (([0, 0], [0, 0]), "moves must be 3 integers"),
        (([0, 0, 0, 0], [0, 0, 0, 0]), "moves must be 3 integers"),
        (([[0, 0, 0]], [[0, 0, 0]]), "moves must be 3 integers"),
        (([0, [1, 2], 0], [0, 0, 0]), "moves must be 3 integers"),
        ((0, 0), "moves must be 3 integers"),
        (([0, 0, 0], [0, 0, 0], [0, 0, 0]), "expected a pair"),
        (5, "expected a pair"),
        ({"moves": [0, 0, 0], "levels": [0, 0, 0]}, "expected a pair"),
        ("ab", "expected a pair"),
    ],
)
def test_simulation_step_refuses_bad_actions_before_anything_moves(scenario, actions, words):
    sim = Simulation(scenario)
    t, truth, agents = _state(sim)
    with pytest.raises(ValueError, match=r"^actions: .*" + words):
        sim.step(actions)
    assert sim.t == t and sim.truth.rng.bit_generator.state == truth and np.array_equal(sim.team.positions, agents)
    sim.step(([0, 0, 0], [0, 0, 0]))  # the simulation is intact: a good action still steps it
    assert sim.t == 1


def test_a_move_out_of_the_area_is_refused_naming_the_agent():
    # agent 1 on the floor: every displacement with a downward component leaves the area
    s = load_scenario("paper-fig3", FAST + ["agents.initial=[[30, 30, 30], [20, 10, 0], [10, 15, 15]]"])
    sim = Simulation(s)
    D = sim.c.displacements
    down = int(np.flatnonzero(D[:, 2] < 0)[0])
    with pytest.raises(ValueError, match=rf"^actions: moves\[1\] = {down} takes agent 1 out of the area"):
        sim.step(([0, down, 0], [0, 0, 0]))
    assert sim.t == 0
    up = int(np.flatnonzero(D[:, 2] > 0)[0])
    rec = sim.step(([0, up, 0], [0, 0, 0]))
    assert np.allclose(rec.agents["pos"][1] - rec.agents["prev"][1], D[up])


def test_numpy_integers_of_any_width_are_actions(scenario):
    sim = Simulation(scenario)
    rec = sim.step((np.array([0, 5, 10], dtype=np.uint8), np.array([1, 2, 3], dtype=np.int32)))
    assert rec.agents["level_index"].tolist() == [1, 2, 3]
    assert np.allclose(rec.agents["pos"] - rec.agents["prev"], sim.c.displacements[[0, 5, 10]])


def test_simulation_step_after_the_end_is_refused(scenario):
    sim = Simulation(scenario)
    while not sim.done:
        sim.step()
    with pytest.raises(RuntimeError, match="ended"):
        sim.step(([0, 0, 0], [0, 0, 0]))


AGENTS = ["agent_0", "agent_1", "agent_2"]


def _actions(**changed):
    return {**{a: np.array([0, 0]) for a in AGENTS}, **changed}


@pytest.mark.parametrize(
    "actions, words",
    [
        (None, r"^actions: expected a dict \{agent: \[move, level\]\}, got NoneType$"),
        ([np.array([0, 0])] * 3, r"^actions: expected a dict .*got list$"),
        (_actions(agent_0=np.array([-1, 0])),  # an array is shown as the list it holds, as a list would be
         r"^agent_0: action \[-1, 0\] is outside the action space MultiDiscrete\(\[\d+, \d+\]\) "
         r"\(\[move, level\] indices\)$"),
        (_actions(agent_0=[-1, 0]), r"^agent_0: action \[-1, 0\] is outside the action space MultiDiscrete"),
        (_actions(agent_1=np.array([0, N_LEVELS])), r"^agent_1: action .* is outside the action space"),
        (_actions(agent_2=np.array([0.5, 0])), r"^agent_2: action .* is outside the action space"),
        (_actions(agent_0=np.array([np.nan, 0])), r"^agent_0: action .* is outside the action space"),
        (_actions(agent_0=np.array([0, 0, 0])), r"^agent_0: action .* is outside the action space"),
        (_actions(agent_0=None), r"^agent_0: action None is outside the action space"),
        (_actions(agent_0=np.array([True, False])), r"^agent_0: action .* is outside the action space"),
        ({"agent_0": np.array([0, 0])}, r"^no action for agent_1: every agent acts at every step$"),
        (_actions(agent_9=np.array([0, 0])), r"^unknown agent 'agent_9'; the agents are agent_0, agent_1, agent_2$"),
        (_actions(**{"5": np.array([0, 0])}), r"^unknown agent '5'"),
    ],
)
def test_env_step_refuses_bad_actions_before_anything_moves(scenario, actions, words):
    env = parallel_env(scenario)
    env.reset(seed=1)
    with pytest.raises(ValueError, match=words):
        env.step(actions)
    assert env.sim.t == 0
    env.step(_actions())
    assert env.sim.t == 1


def test_env_step_before_reset_says_reset_first(scenario):
    env = parallel_env(scenario)
    with pytest.raises(RuntimeError, match=r"^step\(\) before reset\(\): call reset\(\) to start an episode$"):
        env.step(_actions())


def test_env_step_after_the_episode_says_it_ended(scenario):
    env = parallel_env(scenario)
    env.reset(seed=1)
    while env.agents:
        env.step(_actions())
    with pytest.raises(RuntimeError, match=r"^step\(\) after the episode ended \(truncated after 3 steps\)"):
        env.step(_actions())


def test_env_after_close_refuses_step_and_render_until_reset(scenario):
    # close() had done nothing: the closed environment went on stepping and rendering
    env = parallel_env(scenario, render_mode="rgb_array")
    env.reset(seed=1)
    env.step(_actions())
    env.close()
    assert env.agents == []
    with pytest.raises(RuntimeError, match=r"^step\(\) after close\(\): call reset\(\) to start a new episode$"):
        env.step(_actions())
    with pytest.raises(RuntimeError, match=r"^render\(\) after close\(\): call reset\(\)"):
        env.render()
    assert env.sim.t == 1
    env.reset(seed=1)
    env.step(_actions())
    assert env.sim.t == 1 and env.agents == env.possible_agents


@pytest.mark.parametrize("seed", [-1, 1.5, "3", 2**63, np.uint64(2**63), True, float("nan"), [1]])
def test_env_reset_refuses_a_bad_seed_and_keeps_its_episode(scenario, seed):
    env = parallel_env(scenario)
    env.reset(seed=4)
    env.step(_actions())
    with pytest.raises(ValueError, match=r"^reset\(seed=.*\): the seed must be an integer in \[0, 2\^63 - 1\]$"):
        env.reset(seed=seed)
    assert env.sim.t == 1 and env.sim.c.seed == 4


@pytest.mark.parametrize("seeds", [5, None, "12", b"1"])
def test_rollout_refuses_seeds_that_are_not_a_list_of_them(scenario, seeds):
    env = parallel_env(scenario)
    with pytest.raises(ValueError, match=r"^rollout: seeds must be an iterable of integers >= 0"):
        rollout(env, random_policy(env), seeds)


@pytest.mark.parametrize("progress, kind", [(5, "int"), ("bar", "str"), (True, "bool")])
def test_simulate_refuses_a_progress_that_is_not_callable_before_the_first_step(scenario, monkeypatch, progress, kind):
    # it failed after the first step ("'int' object is not callable"), the step's work done
    import trackjam
    from trackjam.simulation import loop

    stepped = []
    real = loop.Simulation.step
    monkeypatch.setattr(loop.Simulation, "step", lambda self, *a, **k: stepped.append(1) or real(self, *a, **k))
    with pytest.raises(TypeError, match=rf"^progress: expected a callable \(t, steps\) or None, got {kind}$"):
        trackjam.simulate(scenario, progress=progress)
    assert stepped == []
    seen = []
    trackjam.simulate(scenario, progress=lambda t, n: seen.append((t, n)))
    assert seen == [(1, 3), (2, 3), (3, 3)]


def test_a_keyword_of_more_digits_than_python_prints_is_named():
    # load_scenario(seed=10**5000) was Python's "Exceeds the limit (4300 digits)" while building the label
    from trackjam.errors import ConfigError

    for key in ("seed", "steps"):
        with pytest.raises(ConfigError, match=rf"^load_scenario\({key}=<an integer of about 5001 digits>\): {key}: "):
            trackjam.load_scenario("paper-fig3", **{key: 10**5000})


def test_a_keyword_holding_an_array_keeps_the_message_on_one_line():
    import numpy as np

    from trackjam.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        trackjam.load_scenario("paper-fig3", agents__initial=np.full((3, 3), 5e5))
    assert "\n" not in str(err.value) and str(err.value).startswith("load_scenario(agents__initial=array([[")


@pytest.mark.parametrize("overrides", [{"steps=5", "steps=6"}, frozenset(["steps=5"]), {"steps=5": 1}])
def test_overrides_without_an_order_are_refused(overrides):
    # a set's order changes between processes: {'steps=5', 'steps=6'} gave 5 in some and 6 in others
    from trackjam.errors import ConfigError

    with pytest.raises(ConfigError, match=r"^overrides: a list of 'key=value' texts, in order \(not a "):
        trackjam.load_scenario("paper-fig3", overrides)


@pytest.mark.parametrize("name", [None, 5, b"paper-fig3", 1.5])
def test_a_scenario_that_is_neither_a_name_nor_a_path_is_named(name):
    from trackjam.errors import ConfigError

    with pytest.raises(ConfigError, match=r"^scenario: a preset name or a path to a YAML/TOML file, got "):
        trackjam.load_scenario(name)


def test_a_preset_given_as_a_path_says_how_a_preset_is_named(tmp_path, monkeypatch):
    from pathlib import Path

    from trackjam.errors import ConfigError

    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError, match=r"^paper-fig3: no such file; the preset of that name is named by a text"):
        trackjam.load_scenario(Path("paper-fig3"))


def test_with_seed_keeps_the_scenarios_seed_range():
    from trackjam.simulation.build import with_seed

    s = trackjam.load_scenario("paper-fig3")
    assert with_seed(s, 2**63 - 1).seed == 2**63 - 1
    for bad in (2**63, -1, 1.0, True):
        with pytest.raises(ValueError, match=r"must be an integer in \[0, 2\^63 - 1\]"):
            with_seed(s, bad)


def test_write_run_checks_its_arguments_before_writing(tmp_path):
    from trackjam.simulation.output import write_run

    r = trackjam.simulate(trackjam.load_scenario("paper-fig3", ["steps=1", "filter.particles=100",
                                                                "filter.birth_particles=20", "control.solver=exact"]))
    for args, kw, error, words in [
        (("x", tmp_path / "a"), {}, TypeError, "result must be"),
        ((r, None), {}, TypeError, "out: expected a folder's path as text, got NoneType None"),
        ((r, 5), {}, TypeError, "out: expected a folder's path as text, got int 5"),
        ((r, ""), {}, ValueError, "out: expected a folder's path, got an empty text"),
        ((r, tmp_path / "b"), {"figures": "no"}, TypeError, "figures must be True or False"),
    ]:
        with pytest.raises(error, match=f"^write_run: {words}"):
            write_run(*args, **kw)
    with pytest.raises(ValueError, match="^write_run: out: holds a NUL character"):  # os's "embedded null byte"
        write_run(r, str(tmp_path / "w\x005"), figures=False)

    class BytesPath:  # a path-like whose path is bytes
        def __fspath__(self):
            return bytes(tmp_path / "w")

    with pytest.raises(TypeError, match="^write_run: out: expected a folder's path as text, got BytesPath"):
        write_run(r, BytesPath(), figures=False)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("preset", ["paper-fig3", "swarm-3"])
def test_a_result_before_the_first_step_is_refused_in_words(preset):
    # it was KeyError: 'jammed' from inside the summary (numpy warned of an empty mean for swarm-3)
    from trackjam.simulation.engine import Simulation
    from trackjam.simulation.loop import simulate
    from trackjam.simulation.swarm import SwarmSimulation

    s = trackjam.load_scenario(preset, ["filter.particles=100", "filter.birth_particles=20"])
    sim = Simulation(s) if preset == "paper-fig3" else SwarmSimulation(s)
    with pytest.raises(RuntimeError, match=r"^result\(\) before the first step: call step\(\) first$"):
        sim.result()
    with pytest.raises(ConfigError, match=r"^scenario: steps: Input should be greater than or equal to 1$"):
        simulate(s.model_copy(update={"steps": 0}))  # a copy that skipped validation had run no step


def test_overrides_in_a_numpy_array_are_read_in_order():
    # `overrides or []` asked the array for its truth value: "ambiguous" ValueError
    import numpy as np

    assert trackjam.load_scenario("paper-fig3", np.array(["steps=5", "steps=6"])).steps == 6
    assert trackjam.load_scenario("paper-fig3", np.array([], dtype=str)).steps == 30


def test_a_keyword_holding_an_integer_past_4300_digits_inside_a_list_is_named():
    from trackjam.errors import ConfigError

    # it was Python's "Exceeds the limit (4300 digits)" while the message's label was made
    with pytest.raises(ConfigError, match=r"^load_scenario\(agents__initial=\[\[<an integer of about 5001 digits>, 0, 0\]\]\): "
                                          r"agents\.initial\.0\.0: must be a finite number, got an integer of 5001 digits$"):
        trackjam.load_scenario("paper-fig3", agents__initial=[[10**5000, 0, 0]])


def test_rollout_reads_a_generator_of_seeds_as_it_goes():
    import itertools

    env = parallel_env(load_scenario("paper-fig3", ["steps=2", "filter.particles=100", "filter.birth_particles=20",
                                                    "control.solver=greedy"]))
    rows = rollout(env, random_policy(env, 0), itertools.islice(itertools.count(5), 2))
    assert [r["seed"] for r in rows] == [5, 6]


@pytest.mark.parametrize("preset", ["paper-fig3", "swarm-3"])
def test_a_step_that_ends_half_done_leaves_the_run_broken_until_reset(preset, monkeypatch):
    # stepping on after a solver raised mid-step gave a run with a step missing (t = [2, 3]),
    # which write_run wrote without a word
    from trackjam.simulation.engine import Simulation
    from trackjam.simulation.swarm import SwarmSimulation

    s = trackjam.load_scenario(preset, ["filter.particles=100", "filter.birth_particles=20", "steps=3"])
    sim = Simulation(s) if preset == "paper-fig3" else SwarmSimulation(s)
    target = sim.team if preset == "paper-fig3" else sim
    name = "decide" if preset == "paper-fig3" else "_aims"
    original = getattr(target, name)

    def boom(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(target, name, boom)
    with pytest.raises(RuntimeError, match="boom"):
        sim.step()
    monkeypatch.setattr(target, name, original)
    for call in (sim.step, sim.result):
        with pytest.raises(RuntimeError, match=r"^step 1 ended half done \(RuntimeError: boom\): the run cannot go on; "
                                               r"call reset\(\)$"):
            call()
    sim.reset()
    while not sim.done:
        sim.step()
    assert list(sim.result().steps["t"] if preset == "paper-fig3" else sim.result().tables["steps"]["t"]) == [1, 2, 3]


@pytest.mark.parametrize(
    "update, words",
    [
        ({"steps": -1}, r"^scenario: steps: Input should be greater than or equal to 1$"),
        ({"steps": "5"}, r"^scenario: steps: must be an integer"),
        ({"seed": -5}, r"^scenario: seed: Input should be greater than or equal to 0$"),
        ({"filter": {"particles": 10**12}}, r"^scenario: filter\.particles: Input should be less than or equal to"),
    ],
)
def test_a_scenario_copied_past_validation_is_refused_by_every_engine(update, words):
    # pydantic's model_copy(update=...) checks nothing: steps=-1 had run no step and then failed
    # in result(), a text failed deep in the engine, 10^12 particles went past the memory check
    s = load_scenario("paper-fig3", steps=3)
    if "filter" in update:
        update = {"filter": s.filter.model_copy(update=update["filter"])}
    bad = s.model_copy(update=update)
    for make in (trackjam.simulate, Simulation, parallel_env):
        with pytest.raises(ConfigError, match=words):
            make(bad)


def test_a_valid_copy_runs_as_the_loaded_scenario_does():
    s = load_scenario("paper-fig3", steps=3)
    copied = load_scenario("paper-fig3").model_copy(update={"steps": 3})
    a, b = trackjam.simulate(s), trackjam.simulate(copied)
    assert a.steps.keys() == b.steps.keys()
    for k in set(a.steps) - {"solve_s", "step_s"}:  # all but the wall times
        np.testing.assert_array_equal(a.steps[k], b.steps[k])
