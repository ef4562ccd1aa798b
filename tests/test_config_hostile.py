"""A hostile user's scenarios beyond the one-target engine's: several targets (the swarm
engine's resources), the comms faults' integers, YAML aliases that expand without end, and a
list of thousands of bad entries. Each is refused in one line naming the key, up front."""

import time

import numpy as np
import pytest

import trackjam
from trackjam.config import load_scenario
from trackjam.config import limits
from trackjam.config.limits import candidates_bound, estimate, measurements_bound
from trackjam.config.loading import MAX_DEPTH, MAX_SHOWN, MAX_VALUES, _check_size
from trackjam.errors import ConfigError

SMALL = ["filter.particles=300", "filter.birth_particles=60", "steps=4"]


def _refused(base: str, overrides: list[str]) -> str:
    with pytest.raises(ConfigError) as err:
        load_scenario(base, overrides)
    message = str(err.value)
    assert "\n" not in message
    return message


@pytest.mark.parametrize(
    "overrides, key, words",
    [
        # one-target figures (the particles of one Bernoulli filter per agent) let these through,
        # and the swarm engine then held a track of n particles per target on every agent
        (["filter.particles=10000000"], "filter.particles", "memory"),
        (["filter.particles=1000000"], "filter.particles", "operations"),
        (["sensor.clutter_rate=1000"], "sensor.clutter_rate", "operations"),
        (["filter.birth_particles=10000000"], "filter.birth_particles", "memory"),
        # the plan's gains span min(K, 4) aims per agent: 16 times the one-target table
        (["agents.n_inclination=40", "agents.n_azimuth=40", "agents.radial_steps=[1,2,3,4,5,6]"],
         "agents.n_inclination", "memory"),
    ],
)
def test_a_swarm_run_past_the_machine_is_refused_naming_the_key(overrides, key, words):
    message = _refused("swarm-3", overrides)
    assert message.startswith(f"--set {overrides[0]}: {key}:") and words in message


def test_the_same_settings_with_one_target_still_pass():
    # the swarm figures apply to the swarm engine only
    s = load_scenario("paper-fig3", ["agents.n_inclination=40", "agents.n_azimuth=40",
                                     "agents.radial_steps=[1,2,3,4,5,6]"])
    assert (s.agents.n_inclination, s.agents.n_azimuth, len(s.agents.radial_steps)) == (40, 40, 6)
    load_scenario("paper-fig3", ["filter.particles=1000000"])


def test_the_swarm_constants_mirror_the_engine():
    from trackjam.estimation.lmb import LMBParams
    from trackjam.simulation.build import LMB_BIRTH_RATE, lmb_params
    from trackjam.simulation.swarm import MAX_AIMS

    p = lmb_params(load_scenario("swarm-3"))
    assert limits.MAX_TRACKS == p.max_tracks == LMBParams.max_tracks
    # sum_j r_B(y_j) <= lambda_B and a birth below the pruning threshold is dropped
    assert limits.MAX_BIRTHS == round(LMB_BIRTH_RATE / p.prune)
    assert limits.MAX_AIMS == MAX_AIMS


def test_the_bounds_the_engines_packages_mirror_are_the_configurations():
    from trackjam.env import observation
    from trackjam.estimation import lmb
    from trackjam.metrics import multi
    from trackjam.radio import measurement

    assert observation.MAX_AGENTS == limits.MAX_AGENTS
    assert (lmb.MAX_SPEED, lmb.MAX_ACCEL_VAR) == (limits.MAX_SPEED, limits.MAX_ACCEL_VAR)
    assert multi.MAX_LENGTH == limits.MAX_LENGTH
    rate = measurement.CLUTTER_RATE_MAX
    assert load_scenario("paper-fig3", [f"sensor.clutter_rate={rate}"]).sensor.clutter_rate == rate
    with pytest.raises(ConfigError, match="clutter_rate"):
        load_scenario("paper-fig3", [f"sensor.clutter_rate={rate * 1.001}"])


def test_the_particle_estimate_bounds_what_the_agents_hold_in_a_short_run():
    from trackjam.simulation.swarm import SwarmSimulation

    s = load_scenario("swarm-3", SMALL)
    n_agents, m = s.n_agents, measurements_bound(s.sensor.clutter_rate)
    bound = estimate(s)["memory_particles"][0] / (8.0 * 14 * n_agents)  # particles per agent
    assert bound < 20 * s.filter.particles  # it is not the worst case of every track confirmed
    sim = SwarmSimulation(s)
    most = 0
    while not sim.done:
        sim.step()
        for agent in sim.agents:
            held = sum(len(t.X) for t in agent.filter.tracks) + sum(len(t.X) for t in agent.filter._births)
            most = max(most, held)
    assert 0 < most <= bound
    assert m > 0


def test_the_table_estimate_bounds_the_assignment_arrays():
    from trackjam.control.assignment import build_assignment
    from trackjam.simulation.build import build_swarm

    s = load_scenario("swarm-3", SMALL)
    c = build_swarm(s).base
    n, k = s.n_agents, limits.MAX_AIMS
    aims = np.array([[20.0, 20.0, 20.0], [75.0, 25.0, 40.0], [50.0, 80.0, 30.0], [40.0, 40.0, 40.0]])
    problem = build_assignment(c.initial_positions, aims[:min(k, len(s.targets))], c.displacements, c.antenna,
                               c.low, c.high, s.control.at_least, True)
    held = problem.gain.nbytes + problem.pz.nbytes + sum(p.gain.nbytes + p.p_d.nbytes for p in problem.targets)
    C = candidates_bound(len(s.agents.radial_steps), s.agents.n_inclination, s.agents.n_azimuth)
    assert problem.n_slots <= C and problem.n_agents == n
    assert held <= estimate(s)["memory_tables"][0]


@pytest.mark.parametrize(
    "item, key, words",
    [
        ("comms.delay_steps=true", "comms.delay_steps", "must be an integer, got bool"),
        ('comms.delay_steps="2"', "comms.delay_steps", "must be an integer, got str"),
        ("comms.delay_steps=1e308", "comms.delay_steps", "must be an integer, got float"),
        ("comms.failures=[{agent: true, step: 1, mode: breakdown}]", "comms.failures.0.agent", "got bool"),
        ('comms.failures=[{agent: "0", step: 1, mode: breakdown}]', "comms.failures.0.agent", "got str"),
        ("comms.failures=[{agent: 0, step: 10000000000000000000000, mode: breakdown}]", "comms.failures.0.step",
         "less than or equal to 100000"),
        ("comms.failures=[{agent: 0, step: 1.0e+308, mode: breakdown}]", "comms.failures.0.step", "must be an integer"),
    ],
)
def test_the_comms_integers_are_integers_within_bounds(item, key, words):
    message = _refused("paper-fig3", [item])
    assert f": {key}: " in message and words in message


def test_too_many_failures_are_refused():
    failures = ", ".join("{agent: 0, step: %d, mode: publisher}" % (k + 1) for k in range(1001))
    assert "comms.failures: List should have at most 1000 items" in _refused("paper-fig3", [f"comms.failures=[{failures}]"])


def _alias_bomb(levels: int) -> str:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, levels)]
    return "\n".join(lines) + f"\ntargets: [*a{levels - 1}]\n"


@pytest.mark.parametrize("where", ["file", "set"])
def test_yaml_aliases_that_expand_to_billions_are_refused_at_once(tmp_path, where):
    started = time.process_time()
    if where == "file":
        f = tmp_path / "bomb.yaml"
        f.write_text(_alias_bomb(9))  # 10^9 values from 10 lines
        message = _refused(str(f), [])
        assert message.startswith(f"{f}: its aliases")
    else:
        value = "[&a [1,1,1,1,1,1,1,1,1,1], " + ", ".join(
            f"&{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]" for i in range(7)) + "]"
        message = _refused("paper-fig3", [f"targets={value}"])
        assert message.startswith("--set targets: its aliases")
    assert f"more than {MAX_VALUES:,} values" in message
    assert time.process_time() - started < 60  # not a speed claim: the unchecked load never ended


def test_the_size_count_stops_at_the_cap_and_counts_every_use_of_an_alias():
    shared = list(range(10))
    _check_size({"a": [shared] * 10})  # 1 + 1 + 10 * 11 values
    with pytest.raises(Exception, match="more than"):
        _check_size([[shared] * 1000] * 1000)  # 10^7 values as read, 1,011 objects


def test_an_ordinary_alias_still_works(tmp_path):
    f = tmp_path / "alias.yaml"
    f.write_text("agents:\n  initial: &p [[1, 1, 1], [5, 5, 5], [9, 9, 9]]\n  initial_aim: [20, 20, 20]\n")
    assert load_scenario(str(f)).agents.initial[1] == (5.0, 5.0, 5.0)


def test_a_list_of_thousands_of_bad_entries_lists_a_few_and_counts_the_rest(tmp_path):
    f = tmp_path / "many.yaml"
    f.write_text("targets:\n" + "  - {id: 1, bogus: 2}\n" * 20000)
    message = _refused(str(f), [])
    assert message.count("unknown key") == MAX_SHOWN
    assert message.endswith(f"and {20000 - MAX_SHOWN} more problems") and len(message) < 2000


@pytest.mark.parametrize(
    "name, text",
    [
        ("deep.yaml", "steps: " + "[" * 100_000 + "]" * 100_000 + "\n"),  # the parser's recursion gave out
        ("deep.toml", "steps = " + "[" * 100_000 + "]" * 100_000 + "\n"),
        ("maps.yaml", "a: " + "{b: " * 5000 + "1" + "}" * 5000 + "\n"),
        ("parsed.yaml", "a: " + "{b: " * (MAX_DEPTH + 5) + "1" + "}" * (MAX_DEPTH + 5) + "\n"),  # parsed, then refused
    ],
)
def test_values_nested_past_any_scenario_are_refused_in_one_line(tmp_path, name, text):
    f = tmp_path / name
    f.write_text(text)
    assert _refused(str(f), []) == f"{f}: nested more than {MAX_DEPTH} levels deep; a scenario nests a few"


def test_a_set_nested_past_any_scenario_is_refused_in_one_line():
    message = _refused("paper-fig3", ["steps=" + "[" * 50_000 + "]" * 50_000])
    assert message == f"--set steps: nested more than {MAX_DEPTH} levels deep; a scenario nests a few"


@pytest.mark.parametrize("overrides", ["steps=3", b"steps=3", [3], [None], 5])
def test_overrides_that_are_not_a_list_of_texts_are_named(overrides):
    # a lone text was read a character at a time ("--set 's': expected key=value")
    with pytest.raises(ConfigError, match=r"^overrides: a list of 'key=value' texts, got "):
        load_scenario("paper-fig3", overrides)


def test_overrides_may_be_any_iterable_of_texts():
    assert load_scenario("paper-fig3", (item for item in ["steps=3"])).steps == 3
    assert load_scenario("paper-fig3", ("steps=4",)).steps == 4


@pytest.mark.parametrize(
    "text, kind",
    [("? [a, b]\n: 1\n", "list"), ("? {a: 1}\n: 1\n", "dict"), ("agents: {? [1]: 2}\n", "list")],
)
def test_a_yaml_key_that_is_a_list_or_a_mapping_is_one_line(tmp_path, text, kind):
    # it was a TypeError (unhashable) from the duplicate-key check
    f = tmp_path / "keys.yaml"
    f.write_text(text)
    assert _refused(str(f), []) == f"{f}: not valid YAML: a key must be a name, got a {kind} (line {text.count(chr(10), 0, text.index('?')) + 1})"


def test_the_swarm_log_estimate_covers_the_columns_a_run_holds():
    s = load_scenario("swarm-3", SMALL + ["sensor.clutter_rate=50"])
    result = trackjam.simulate(s)
    held = sum(np.asarray(v).nbytes for table in result.tables.values() for v in table.values())
    assert held <= estimate(s)["memory_logs"][0]
    # and not by orders of magnitude: the estimate is 4 times the rows' bytes
    assert estimate(s)["memory_logs"][0] < 40 * held


# -- integers past Python's 4300 digits (int("9" * 5000) raises ValueError) -------------------

LONG = "9" * 5000


@pytest.mark.parametrize(
    "item, message",
    [
        (f"steps={LONG}", "steps: integer too large (5000 digits)"),
        (f"targets=[{{id: {LONG}}}]", "targets.0.id: integer too large (5000 digits)"),
        (f"antenna.power_levels_db=[off, {LONG}]",
         "antenna.power_levels_db: power level: integer too large (5000 digits)"),
        (f"agents.initial=[[1, 2, -{LONG}]]", "agents.initial.0.2: integer too large (5000 digits)"),
        # under the limit but past any float: math.isfinite(10**400) raised an OverflowError
        (f"antenna.power_levels_db=[off, {'9' * 400}]",
         "antenna.power_levels_db: power level an integer of 400 digits dBW lies outside [-200, 60] dBW"),
        (f"targets=[{{id: {'9' * 400}}}]",
         "targets.0.id: an integer id must lie within +-(2^63 - 1), got an integer of 400 digits"),
    ],
)
def test_an_integer_of_thousands_of_digits_in_a_set_is_refused_naming_the_key(item, message):
    base = "swarm-3" if "targets" in item else "paper-fig3"
    assert _refused(base, [item]) == f"--set {item[:57]}...: {message}"


def test_an_integer_of_thousands_of_digits_in_a_yaml_file_is_refused_naming_the_key(tmp_path):
    f = tmp_path / "long.yaml"
    f.write_text(f"steps: 3\nfilter:\n  particles: {LONG}\n")
    assert _refused(str(f), []) == f"{f}: filter.particles: integer too large (5000 digits)"


@pytest.mark.parametrize(
    "text, message",
    [
        (f"steps = {LONG}\n", "steps: integer too large (5000 digits, line 1)"),
        (f"steps = 3\n[filter]\nparticles = {LONG}\n", "filter.particles: integer too large (5000 digits, line 3)"),
        (f'name = "x"\n[[targets]]\nid = {LONG}\n', "targets.id: integer too large (5000 digits, line 3)"),
        (f"targets = [{{id = 1}}, {{id = {LONG}}}]\n", "targets.id: integer too large (5000 digits, line 1)"),
        (f"[filter]\nparticles = 1_{LONG}\n", "filter.particles: integer too large (5001 digits, line 2)"),
    ],
)
def test_an_integer_of_thousands_of_digits_in_a_toml_file_is_refused_naming_the_file_and_key(tmp_path, text, message):
    f = tmp_path / "long.toml"
    f.write_text(text)
    assert _refused(str(f), []) == f"{f}: {message}"


def test_an_integer_under_the_limit_is_still_an_integer(tmp_path):
    f = tmp_path / "ok.yaml"
    f.write_text("steps: 0000000000000000000000000000000000000000000000000003\n")
    assert load_scenario(str(f)).steps == 3
    assert load_scenario("paper-fig3", ["steps=1_0"]).steps == 10


# -- --set values that are malformed YAML -------------------------------------------------------


@pytest.mark.parametrize(
    "item, problem",
    [
        ("filter.cue={existence: 1", "expected ',' or '}', but got '<stream end>' (column 14)"),
        ("filter.cue={existence: 1, existence: 0.5}", "duplicate key 'existence' (line 1)"),
        ("agents.initial=[[1, 2, 3], [4, 5, 6]", "expected ',' or ']', but got '<stream end>' (column 22)"),
        ("agents.initial= [[1, 2, 3]]]", "expected '<document start>', but found ']' (column 13)"),
        ("filter.cue={? [a]: 1}", "a key must be a name, got a list (line 1)"),
    ],
)
def test_a_set_value_that_is_malformed_yaml_says_so_naming_the_item(item, problem):
    # they were read as text and refused as "filter.cue: Input should be a valid dictionary"
    assert _refused("paper-fig3", [item]) == f"--set {item}: not valid YAML: {problem}"


@pytest.mark.parametrize("key, text", [("name", "aGVsbG8="), ("control.solver", "Z3Jhc3A=")])
def test_binary_data_is_refused_not_read_as_text(tmp_path, key, text):
    # `name: !!binary aGVsbG8=` named the run "hello" and `control.solver: !!binary ...` chose
    # grasp, without a word: bytes passed for text
    item = f"{key}=!!binary {text}"
    assert _refused("paper-fig3", [item]) == f"--set {item}: not valid YAML: binary data (!!binary) is not a scenario value (line 1)"
    f = tmp_path / "s.yaml"
    section, _, field = key.rpartition(".")
    f.write_text(f"steps: 3\n{section}:\n  {field}: !!binary {text}\n" if section else f"steps: 3\n{key}: !!binary {text}\n")
    message = _refused(str(f), [])
    assert message == f"{f}: not valid YAML: binary data (!!binary) is not a scenario value (line {3 if section else 2})"


def test_a_long_malformed_set_item_is_shortened():
    item = "agents.initial=[" + ", ".join(["[1, 2, 3]"] * 20)
    message = _refused("paper-fig3", [item])
    assert message.startswith(f"--set {item[:57]}...: not valid YAML: expected ',' or ']'") and len(message) < 200


@pytest.mark.parametrize("kind", ["set", "toml", "yaml", "duplicate"])
def test_a_long_key_is_shortened_in_the_message(tmp_path, kind):
    # the key was echoed whole: an unknown key of 100 kB (a --set item, a quoted TOML key, an
    # explicit YAML key) or one given twice made a line of 100 kB
    key = "k" * 100_000
    if kind == "set":
        message = _refused("paper-fig3", [f"filter.{key}=1"])
    else:
        f = tmp_path / ("s.toml" if kind == "toml" else "s.yaml")
        f.write_text({"toml": f'steps = 3\n"{key}" = 1\n', "yaml": f"steps: 3\n? {key}\n: 1\n",
                      "duplicate": f"steps: 3\n? {key}\n: 1\n? {key}\n: 2\n"}[kind])
        message = _refused(str(f), [])
    assert len(message) < 300 and "kkkkkkkk..." in message
    assert message.endswith("unknown key") or "duplicate key 'kkk" in message


def test_a_long_key_under_a_value_is_shortened_in_the_message():
    # "--set steps.kkk...=1: steps is not a section" echoed the whole key (100 kB)
    key = "k" * 100_000
    assert _refused("paper-fig3", [f"steps.{key}=1"]) == f"--set steps.{key[:51]}...: steps is not a section"
    assert len(_refused("paper-fig3", [f"{key}=1", f"{key}.x=1"])) < 300


def test_a_set_value_that_is_not_yaml_and_not_a_flow_collection_is_still_text():
    # "a: b: c" is no YAML: the value is that text, refused by the name's own rule
    message = _refused("paper-fig3", ["name=a: b: c"])
    assert message.startswith("--set name=a: b: c: name: 'a: b: c' is not a safe folder name")


# -- scenario files by their extension ---------------------------------------------------------------


@pytest.mark.parametrize("name", ["s.yaml", "s.yml", "s.YML", "s.Yaml", "s.YAML"])
def test_a_yaml_file_is_read_whatever_the_case_of_its_extension(tmp_path, name):
    f = tmp_path / name
    f.write_text("steps: 3\n")
    assert load_scenario(str(f)).steps == 3


@pytest.mark.parametrize("name", ["s.toml", "s.TOML", "s.Toml"])
def test_a_toml_file_is_read_whatever_the_case_of_its_extension(tmp_path, name):
    f = tmp_path / name
    f.write_text("steps = 3\n")
    assert load_scenario(str(f)).steps == 3


@pytest.mark.parametrize("name, what", [("s.txt", "unknown extension '.txt'"), ("s.json", "unknown extension '.json'"),
                                        ("scenario", "no extension"), ("s.yaml.bak", "unknown extension '.bak'")])
def test_a_file_of_another_extension_is_refused_naming_the_accepted_ones(tmp_path, name, what):
    f = tmp_path / name
    f.write_text("steps: 3\n")  # it was read as YAML without a word
    assert _refused(str(f), []) == f"{f}: {what}: a scenario file ends in .yaml, .yml or .toml (any case)"


def test_an_empty_file_is_empty_whatever_its_name(tmp_path):
    f = tmp_path / "empty.txt"
    f.write_text("")
    assert _refused(str(f), []).startswith(f"{f}: is empty")
    assert _refused("/dev/null", []).startswith("/dev/null: is empty")


# -- planning over the belief (control.plan_over: belief) -----------------------------------------

AGENTS_32 = "agents.initial=[" + ",".join("[%d,%d,30]" % (5 + i % 6 * 15, 5 + i // 6 * 15) for i in range(32)) + "]"


def test_planning_over_a_belief_too_large_for_a_step_is_refused_naming_belief_samples():
    # one step of this ran 88 s (exact, 32 agents x 256 points each) while validate said ok
    items = ["steps=1", AGENTS_32, "control.belief_samples=256", "control.belief_spread=null", "target.occlusions=[]"]
    assert _refused("pursuit", items) == (
        "--set control.belief_samples=256: control.belief_samples: one step would take about 8.4e+09 operations "
        "(belief), past the cap of 1e+09; lower control.belief_samples")


def test_grasp_over_the_belief_costs_the_points_times_the_point_search():
    # 3 agents x 256 points: each of GRASP's 10^6 joint samples is evaluated at 768 points (4 min a step)
    assert _refused("paper-fig3", ["control.plan_over=belief", "control.belief_samples=256"]) == (
        "--set control.belief_samples=256: control.belief_samples: one step would take about 6.9e+09 operations "
        "(grasp), past the cap of 1e+09; lower control.belief_samples")
    point = estimate(load_scenario("paper-fig3"))["work_grasp"][0]
    belief = estimate(load_scenario("paper-fig3", ["control.plan_over=belief"]))["work_grasp"][0]
    assert belief == 3 * 16 * point


def test_the_belief_figures_grow_with_the_points_and_vanish_when_planning_at_the_point():
    s = load_scenario("pursuit")
    assert "work_belief" not in estimate(load_scenario("pursuit", ["control.plan_over=point"]))
    small, large = (estimate(load_scenario("pursuit", [f"control.belief_samples={k}"]))["work_belief"][0]
                    for k in (16, 64))
    assert large == 4 * small and estimate(s)["work_belief"][1] == ("control.belief_samples", "agents.initial")


@pytest.mark.parametrize("preset", ["pursuit", "paper-fig3", "swarm-3", "paper-fig3-literal"])
def test_the_presets_pass_the_work_check(preset):
    s = load_scenario(preset)
    assert all(ops <= limits.MAX_STEP_WORK for name, (ops, _) in estimate(s).items() if name.startswith("work_"))


def test_every_experiments_scenarios_pass_the_work_check():
    from trackjam.experiments.definitions import EXPERIMENTS, get_experiment
    from trackjam.experiments.engine import _plan

    for name in EXPERIMENTS:
        scenarios, _ = _plan(get_experiment(name), 2, 30, 0, [])  # built and validated, or ConfigError
        assert scenarios


# -- a TOML file with no key (tomllib reads an empty text as an empty table) ----------------------


@pytest.mark.parametrize("text", ["", "\n\n", "# only a comment\n", "   \n# two\n# comments\n"])
def test_a_toml_file_without_a_key_is_empty_as_a_yaml_one_is(tmp_path, text):
    # it validated as the default scenario ("ok: scenario, 3 agents, 30 steps") and ran it
    f = tmp_path / "empty.toml"
    f.write_text(text)
    assert _refused(str(f), []) == (f"{f}: is empty (write the keys to change, e.g. from `trackjam show-config`)")


def test_a_toml_file_with_an_empty_table_is_not_empty(tmp_path):
    f = tmp_path / "table.toml"
    f.write_text("[filter]\n")
    assert load_scenario(str(f)).filter.particles == 10_000


# -- a YAML file that does not parse says what and where ------------------------------------------


@pytest.mark.parametrize(
    "text, problem",
    [
        # the first line of PyYAML's text is its context ("while scanning for the next token"), which
        # said neither the problem nor where it is
        ("steps: 3\nfilter:\n\tparticles: 100\n",
         "found character '\\t' that cannot start any token (line 3, column 1; YAML indents with spaces, not tabs)"),
        ("agents: {initial: [[1, 2, 3]}\n", "expected ',' or ']', but got '}' (line 1, column 29)"),
        ("steps: [1, 2\n", "expected ',' or ']', but got '<stream end>' (line 2, column 1)"),
        ('name: "abc\n', "found unexpected end of stream (line 2, column 1)"),
        ("steps: 3\n  x: 1\n", "mapping values are not allowed here (line 2, column 4)"),
        ("steps: 3\n- 1\n", "expected <block end>, but found '-' (line 2, column 1)"),
        ("steps: *nope\n", "found undefined alias 'nope' (line 1, column 8)"),
    ],
)
def test_a_yaml_file_that_does_not_parse_names_the_problem_and_its_line(tmp_path, text, problem):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    assert _refused(str(f), []) == f"{f}: not valid YAML: {problem}"


# -- YAML 1.1's numbers that read as another number ------------------------------------------------


@pytest.mark.parametrize(
    "item, message",
    [
        # base 60: 1:30 was 90 steps, 1:30.5 was 90.5 s, without a word
        ("steps=1:30", "--set steps=1:30: steps: must be an integer, got str '1:30'"),
        ("control.time_limit_s=1:30.5", "--set control.time_limit_s=1:30.5: control.time_limit_s: must be a number, "
                                        "got str '1:30.5'"),
        ("targets=[{id: 1:00}, {id: b}]", None),  # an id may be a text: the text it reads
    ],
)
def test_a_base_60_number_is_a_text_not_another_number(item, message):
    if message is None:
        assert load_scenario("swarm-3", [item]).targets[0].id == "1:00"
    else:
        assert _refused("paper-fig3", [item]) == message


@pytest.mark.parametrize("text, value", [("010", 10), ("0_10", 10), ("-007", -7), ("0", 0), ("00", 0), ("0x10", 16)])
def test_a_leading_zero_does_not_make_an_integer_octal(text, value):
    # YAML 1.1 read 010 as 8
    from trackjam.config.loading import _yaml

    assert _yaml(f"x: {text}\n") == {"x": value}


def test_a_particle_count_with_a_leading_zero_is_the_count_it_reads(tmp_path):
    f = tmp_path / "zero.yaml"
    f.write_text("filter:\n  particles: 010000\n")  # it was 4096
    assert load_scenario(str(f)).filter.particles == 10_000
    assert load_scenario("paper-fig3", ["filter.birth_particles=0100"]).filter.birth_particles == 100


# -- a problem a --set caused is blamed on it, not on the file ----------------------------------


def test_a_section_a_set_creates_without_its_required_keys_is_blamed_on_the_set():
    # paper-fig3 has no filter.visibility: the --set made one, without `reappear`; the preset was blamed
    assert _refused("paper-fig3", ["steps=3", "filter.visibility.hide=0.5"]) == (
        "--set filter.visibility.hide=0.5: filter.visibility.reappear: Field required")


def test_a_section_missing_a_required_key_in_the_file_is_still_the_files(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text("filter:\n  visibility: {hide: 0.5}\n")
    assert _refused(str(f), ["steps=3", "filter.particles=500"]) == f"{f}: filter.visibility.reappear: Field required"


@pytest.mark.parametrize("item", ["target.accel_var=0", "target={accel_var: 0}"])
def test_a_target_set_beside_a_list_of_targets_is_blamed_on_the_set(item):
    # swarm-3 lists its targets: --set target.accel_var=0 adds the one `target`; the preset was blamed
    assert _refused("swarm-3", [item]) == (
        f"--set {item}: give either `target` (one target) or `targets` (a list of them), not both; `target: null` "
        "sets a given target aside")


def test_a_list_of_targets_set_beside_a_files_target_is_blamed_on_the_set():
    assert _refused("paper-fig3", ["targets=[{id: a}, {id: b}]"]).startswith(
        "--set targets=[{id: a}, {id: b}]: give either `target` (one target)")


def test_a_problem_between_keys_is_not_blamed_on_a_set_of_another_key_of_a_section_it_names():
    # "the number of agents" names no key: --set agents.n_azimuth did not make at_least exceed it
    f_items = ["control.at_least=3", "agents.initial=[[30, 30, 30], [20, 10, 10]]"]
    message = _refused("paper-fig3", f_items[:1] + ["agents.n_azimuth=4"] + f_items[1:])
    assert message.startswith("--set agents.initial=") or message.startswith("--set control.at_least=3")
    assert "agents.n_azimuth" not in message


def _float_keys(model, prefix=""):
    """Every dotted key of ``model`` and its sections that holds a float or a list or tuple of them."""
    import typing

    from pydantic import BaseModel

    for name, field in model.model_fields.items():
        kinds = typing.get_args(field.annotation) or (field.annotation,)
        kinds = [typing.get_args(k)[0] if typing.get_origin(k) is typing.Annotated else k for k in kinds]
        for kind in kinds:
            if isinstance(kind, type) and issubclass(kind, BaseModel):
                yield from _float_keys(kind, f"{prefix}{name}.")
        if float in kinds:
            yield f"{prefix}{name}"


FLOAT_KEYS = sorted(set(_float_keys(trackjam.config.Scenario)))


def test_the_float_keys_are_found():
    assert {"antenna.height", "antenna.opening_angle_deg", "filter.cue.position_std", "control.time_limit_s",
            "metrics.gate", "filter.accel_var"} <= set(FLOAT_KEYS)


@pytest.mark.parametrize("value", ["1e308", "-1e308", "1.7976931348623157e308"])
@pytest.mark.parametrize("key", FLOAT_KEYS)
def test_a_float_key_past_any_physics_is_refused_naming_it(key, value):
    # every float key has physical bounds (config/limits.py): a hand-edited 1e308 is one line
    # naming the key, never a run whose arithmetic overflows (an unbounded Real() would pass it)
    base = "swarm-3" if key.startswith("targets") else "pursuit"
    section = key.rsplit(".", 1)[0]
    needs = {"filter.cue": "filter.cue={existence: 1, position_std: 1, velocity_std: 1}",
             "filter.visibility": "filter.visibility={hide: 0.1, reappear: 0.5}",
             "filter.mode": "filter.mode={radius: 1, mass: 0.5}",
             "target.stochastic": "target.stochastic={birth_prob: 0.5, survival_prob: 0.5}",
             "target.response": "target.response={threshold_db: -40}",
             "filter.response": "filter.response={action: land}"}
    overrides = [needs[section]] if section in needs else []
    message = _refused(base, overrides + [f"{key}={value}"])
    assert f": {key}: " in message, message


def test_yaml_merge_keys_merge_and_the_keys_given_win(tmp_path):
    # `<<: *base` was "could not determine a constructor for the tag ...merge", naming no key
    f = tmp_path / "s.yaml"
    f.write_text("area:\n  <<: {low: [0, 0, 0], high: [50, 50, 50]}\n  high: [60, 60, 60]\n")
    s = load_scenario(str(f))
    assert list(s.area.low) == [0, 0, 0] and list(s.area.high) == [60, 60, 60]
    f.write_text("area:\n  low: [0, 0, 0]\n  low: [1, 1, 1]\n  high: [50, 50, 50]\n")  # a key given twice still is not
    with pytest.raises(ConfigError, match=r"duplicate key 'low' \(line 3\)"):
        load_scenario(str(f))


def test_a_yaml_set_is_refused_not_read_as_a_list():
    item = "agents.radial_steps=!!set {1: null, 5: null}"
    assert _refused("paper-fig3", [item]) == f"--set {item}: not valid YAML: a set (!!set) is not a scenario value; give a list (line 1)"


def test_a_set_item_that_is_not_utf8_is_refused_naming_the_set():
    # the shell's bytes: `--set $'st\xffeps=1'` blamed the preset for "Input should be a valid string"
    message = _refused("paper-fig3", ["st\udcffeps=1"])
    assert message == "--set st\\udcffeps=1: not valid UTF-8 text (a key or a value holds bytes that are not UTF-8)"


@pytest.mark.parametrize("overrides, blamed, key", [
    (["agents.initial=[[10,10,10]]"], 0, "control.at_least (2) exceeds the number of agents in agents.initial (1)"),
    # both keys set: the one the message starts with, not the --set given first
    (["agents.initial=[[10,10,10],[11,11,11]]", "control.belief_at_least=2", "control.at_least=1",
      "comms.failures=[{agent: 2, step: 1, mode: breakdown}]"], 3, "comms.failures[0].agent 2 is not an agent index"),
    (["comms.failures=[{agent: 2, step: 1, mode: breakdown}]", "agents.initial=[[10,10,10],[11,11,11]]"], 0,
     "comms.failures[0].agent 2 is not an agent index"),
])
def test_a_problem_between_keys_is_blamed_on_the_set_that_caused_it(overrides, blamed, key):
    # it was blamed on the preset: `preset paper-fig3: control.at_least (2) exceeds the number of agents (1)`
    message = _refused("paper-fig3", overrides)
    assert message.startswith(f"--set {overrides[blamed]}: {key}"), message


def test_a_chain_of_merge_keys_is_refused_before_it_copies_without_end(tmp_path):
    # each a_i merges a_(i-1): the keys copied grow as the square of the chain, and 8,000 lines
    # took 68 s and 1.25 GB before the size check of the data could count them
    f = tmp_path / "chain.yaml"
    f.write_text("a0: &a0 {k0: 0}\n" + "".join(f"a{i}: &a{i} {{<<: *a{i - 1}, k{i}: {i}}}\n" for i in range(1, 8000)))
    with pytest.raises(ConfigError, match=r"its merge keys \(<<\) copy more than 1,000,000 keys; a scenario has a few hundred"):
        load_scenario(str(f))


def test_a_merge_source_with_a_key_given_twice_is_refused(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text("area: {<<: {low: [0, 0, 0], low: [1, 1, 1]}, high: [50, 50, 50]}\n")
    with pytest.raises(ConfigError, match=r"duplicate key 'low'"):
        load_scenario(str(f))


def test_an_option_the_swarm_engine_does_not_simulate_is_blamed_on_the_set_that_made_several_targets():
    from trackjam.simulation.build import check_swarm_options

    overrides = ["target=null", "targets=[{initial: [10,10,10,0,0,0]}, {initial: [20,20,20,0,0,0]}]"]
    s = load_scenario("paper-fig3", overrides)
    with pytest.raises(ConfigError) as err:
        check_swarm_options(s, overrides)
    assert str(err.value).startswith("--set targets=[{initial: [10,10,10,0,0,0]}")
    assert "fusion.existence: 'evidence' is not simulated with several targets yet" in str(err.value)
    with pytest.raises(ConfigError) as err:  # without the --set, the message is the key's alone
        check_swarm_options(s)
    assert str(err.value).startswith("fusion.existence: 'evidence'")


def test_an_opening_angle_just_past_its_bound_is_shown_as_given():
    # `got 170` for 170.0001 read as a legal value refused
    assert _refused("paper-fig3", ["antenna.opening_angle_deg=170.0001"]).endswith(
        "opening angle must be in [0.1, 170] deg, got 170.0001")


@pytest.mark.parametrize("item", ["=5", " =5", "area..low=[0,0,0]", ".steps=3"])
def test_a_set_item_with_an_empty_key_is_shown_whole(item):
    # `--set =5` said "--set '': empty key", not the item typed
    assert _refused("paper-fig3", [item]) == f"--set {item!r}: an empty key (before the '=' or between two dots)"


@pytest.mark.parametrize("value, kind", [("2001-12-14", "the date 2001-12-14"), ("yes", "the boolean true"),
                                         ("0x10", "the number 16"), ("1e5", "the number 100000.0")])
def test_a_text_yaml_reads_as_something_else_says_what_it_read_and_how_to_quote(value, kind):
    # `--set name=2001-12-14` said only "Input should be a valid string"
    assert _refused("paper-fig3", [f"name={value}"]) == (
        f"--set name={value}: name: Input should be a valid string (read as {kind}; a text needs quotes: "
        "name: \"...\" in a file, --set 'name=\"...\"' on the command line)")


def test_a_link_that_leads_nowhere_is_said_so(tmp_path):
    # a loop of links was "no such file (and no preset of that name)"
    (tmp_path / "a.yaml").symlink_to(tmp_path / "b.yaml")
    (tmp_path / "b.yaml").symlink_to(tmp_path / "a.yaml")
    with pytest.raises(ConfigError, match="a symbolic link that leads to no file"):
        load_scenario(str(tmp_path / "a.yaml"))


def test_a_section_the_swarm_engine_does_not_simulate_is_shown_as_the_file_says_it():
    from trackjam.simulation.build import check_swarm_options

    s = load_scenario("swarm-3", ["oracle={truth_after_hiding: 2}"])
    with pytest.raises(ConfigError) as err:
        check_swarm_options(s)
    assert str(err.value).startswith("oracle: {'state_before_hiding': False, 'mean_before_hiding': False, "
                                     "'truth_after_hiding': 2,")
    assert str(err.value).endswith("is not simulated with several targets yet; the swarm engine runs with null")
    check_swarm_options(load_scenario("swarm-3", ["comms.failures=[{agent: 0, step: 1, mode: breakdown}]"]))


@pytest.mark.parametrize("fields, words", [
    ({"agents____initial": [[1, 1, 1]]}, r"^load_scenario\(agents____initial=\[\[1, 1, 1\]\]\): empty key$"),
    ({"agents__initial__0": [1, 1, 1]}, r"^load_scenario\(agents__initial__0=\[1, 1, 1\]\): initial is not a section$"),
])
def test_a_bad_keyword_key_is_named_as_the_keyword_not_as_a_set_item(fields, words):
    # they were blamed on "--set 'agents..initial'", which the caller never wrote
    from trackjam.config import load_scenario
    from trackjam.errors import ConfigError

    with pytest.raises(ConfigError, match=words):
        load_scenario("paper-fig3", **fields)


# -- covariance intersection's work (fusion) ------------------------------------------------------

AGENTS_64 = "agents.initial=[" + ",".join("[%d,%d,%d]" % (5 + i % 4 * 25, 5 + i // 4 % 4 * 25, 20 + i // 16 * 15)
                                          for i in range(64)) + "]"
TARGETS_64 = "targets=[" + ",".join("{id: t%d, initial: [%d, %d, 50, 0, 0, 0]}" % (k, 5 + k % 8 * 12, 5 + k // 8 * 12)
                                    for k in range(64)) + "]"


def test_track_fusion_too_large_for_a_step_is_refused_naming_the_agents():
    # 64 targets seen by 64 agents: the swarm engine's track fusion took 56 s of a 76 s step,
    # which the cap did not count
    items = ["steps=2", AGENTS_64, TARGETS_64, "filter.particles=100", "filter.birth_particles=20"]
    assert _refused("swarm-3", items).endswith(  # the message begins with the long --set item
        "agents.initial: one step would take about 4.1e+09 operations (fusion), past the cap of 1e+09; lower agents.initial")


def test_fusion_work_counts_one_fusion_per_inbox():
    from trackjam.config.limits import fusion_ops

    base = ["control.solver=exact", AGENTS_32]
    one = estimate(load_scenario("paper-fig3", base))["work_fusion"][0]
    assert one == fusion_ops(32)
    lossy = estimate(load_scenario("paper-fig3", base + ["comms.loss=0.1"]))["work_fusion"][0]
    assert lossy == 32 * fusion_ops(32)  # every agent fuses an inbox of its own
    coasted = estimate(load_scenario("paper-fig3", base + ["comms.delay_steps=1", "comms.stale=coast"]))
    assert coasted["work_fusion"][0] == 32 * fusion_ops(32)
    assert "work_fusion" not in estimate(load_scenario("paper-fig3", base + ["fusion.share=scans"]))
    assert fusion_ops(2) == fusion_ops(1)  # two estimates: a scalar search, no SLSQP


def test_an_ospa_whose_cutoff_to_the_order_underflows_is_refused():
    # 1e-40^10: the one-target OSPA rounded to 0, and the swarm engine's refused it at the first
    # step in a traceback, after validate had said ok
    for preset in ("paper-fig3", "swarm-3"):
        assert _refused(preset, ["metrics.ospa_cutoff=1e-40", "metrics.ospa_order=10"]) == (
            "--set metrics.ospa_cutoff=1e-40: metrics: ospa_cutoff^ospa_order = 1e-40^10 is below the smallest normal "
            "float, so the OSPA would round to 0; use a larger ospa_cutoff")
    assert load_scenario("swarm-3", ["metrics.ospa_cutoff=1e-40"]).metrics.ospa_cutoff == 1e-40  # 1e-80 is fine


def test_each_agent_builds_its_own_gain_table_when_messages_can_be_lost_or_late():
    # 64 agents with comms.delay_steps: 1 took 19.6 s a step (0.64 s without): every agent plans
    # from its own inbox; the estimate had counted one table
    base = ["control.solver=greedy", AGENTS_32]
    one = estimate(load_scenario("paper-fig3", base))["work_tables"][0]
    for item in ("comms.delay_steps=1", "comms.loss=0.1", "comms.failures=[{agent: 0, step: 3, mode: channel}]"):
        assert estimate(load_scenario("paper-fig3", base + [item]))["work_tables"][0] == 32 * one, item
    assert _refused("paper-fig3", ["control.solver=greedy", AGENTS_64, "comms.delay_steps=1"]).endswith(
        "agents.initial: one step would take about 1.6e+09 operations (tables), past the cap of 1e+09; lower "
        "agents.initial")


def test_grasps_neighbour_lists_and_the_swarm_planners_copies_count_in_the_memory():
    s = load_scenario("paper-fig3")
    C = candidates_bound(len(s.agents.radial_steps), s.agents.n_inclination, s.agents.n_azimuth)
    assert C == 79 and estimate(s)["memory_neighbours"][0] == 40.0 * C * C
    assert "memory_neighbours" not in estimate(load_scenario("paper-fig3", ["control.solver=exact"]))
    swarm = estimate(load_scenario("swarm-3"))["memory_tables"][0]
    N, aims = 5, 3
    once = 8.0 * (N * N * (aims * C) ** 2 + aims * (N * N * C * C + 2 * N * C * 4 + N))
    assert swarm == 3 * once  # measured: about three copies at once (7.6 GB at 64 agents, 2.5 GB counted once)


def test_a_warning_about_many_items_names_three_and_counts_the_rest():
    # 1000 late failures had made one warning line of 20,961 characters
    from trackjam.config.warnings import scenario_warnings

    failures = "comms.failures=[" + ",".join(f"{{agent: 0, step: {40 + k}, mode: channel}}" for k in range(1000)) + "]"
    lines = scenario_warnings(load_scenario("paper-fig3", [failures]))
    assert "comms.failures[0], comms.failures[1], comms.failures[2] and 997 more: start after the last step (30); " \
           "the agent never fails" in lines


@pytest.mark.parametrize(("high", "gate", "warned"), [(1.0, 5.0, True), (100.0, 5.0, False), (2.0, 3.4, False),
                                                      (2.0, 3.5, True)])
def test_a_gate_as_wide_as_the_area_is_warned_about(high, gate, warned):
    """In a 1 m box every confirmed estimate lies within the default 5 m gate of the truth, so the
    track-quality classes count nothing as a false track (the diagonal of a 2 m cube is 3.46 m)."""
    from trackjam.config.warnings import scenario_warnings

    s = load_scenario("paper-fig3", [f"area.high=[{high}, {high}, {high}]", f"metrics.gate={gate}",
                                     "agents.initial=[[0.2, 0.2, 0.2], [0.5, 0.5, 0.5], [0.8, 0.8, 0.8]]",
                                     "target.initial=[0.5, 0.5, 0.5, 0, 0, 0]"])
    lines = [w for w in scenario_warnings(s) if w.startswith("metrics.gate")]
    assert len(lines) == warned
    if warned:
        assert lines[0].startswith(f"metrics.gate: {gate:g} m is at least the area's diagonal")


def test_team_proposals_without_shared_scans_is_warned_about():
    from trackjam.config.warnings import scenario_warnings

    lines = scenario_warnings(load_scenario("paper-fig3", ["filter.team_proposals=true"]))
    assert any(w.startswith("filter.team_proposals: true has no effect under fusion.share: posteriors") for w in lines)
    assert not [w for w in scenario_warnings(load_scenario("pursuit", ["filter.team_proposals=true"]))
                if w.startswith("filter.team_proposals")]


def test_association_misses_with_one_target_is_warned_about():
    from trackjam.config.warnings import scenario_warnings

    lines = scenario_warnings(load_scenario("paper-fig3", ["filter.association_misses=true"]))
    assert any(w.startswith("filter.association_misses: true has no effect with one target") for w in lines)
    assert not [w for w in scenario_warnings(load_scenario("swarm-3", ["filter.association_misses=true"]))
                if w.startswith("filter.association_misses")]


def test_a_long_key_whose_value_is_too_large_is_shortened_in_the_message():
    # "--set kkk...: nested more than 50 levels deep" echoed the whole key (100 kB)
    key = "k" * 100_000
    message = _refused("paper-fig3", [f"{key}={'[' * 60}{']' * 60}"])
    assert "nested more than" in message and len(message) < 300
