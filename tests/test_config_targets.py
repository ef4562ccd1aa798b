"""Several truth targets in the configuration: `targets`, the one `target` as a list of one, ids,
and bad input (one line naming the key, exit 2)."""

import subprocess
import sys

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.config import Scenario, load_scenario, preset_names, scenario_to_yaml, validate_scenario
from trackjam.errors import ConfigError
from trackjam.simulation.build import target_ids, target_params, targets_params
from config_paths import value_paths

TWO = "targets=[{initial: [10, 10, 10, 1, 0, 0]}, {id: b, appears: 4, initial: null, occlusions: [[6, 8]]}]"


def _two(*more):
    return load_scenario("paper-fig3", ["target=null", TWO, *more])


def _same_params(a, b):
    assert a.keys() == b.keys()
    for k in a:
        if isinstance(a[k], np.ndarray) or isinstance(b[k], np.ndarray):
            assert np.array_equal(a[k], b[k])
        else:
            assert a[k] == b[k], k


@pytest.mark.parametrize("name", [n for n in preset_names() if not n.startswith("swarm-")])
def test_a_preset_resolves_as_before_and_is_a_list_of_its_one_target(name):
    s = load_scenario(name)
    assert s.targets is None
    assert "targets" not in scenario_to_yaml(s)  # a preset's scenario.yaml is unchanged
    (only,) = s.target_list
    assert only.id == 0 and only.model_dump(exclude={"id"}) == s.target.model_dump()
    (p,) = targets_params(s)
    _same_params(vars(p), vars(target_params(s)))
    assert target_ids(s) == [0]


def test_ids_default_to_the_index_and_keep_their_given_value():
    s = _two()
    assert [t.id for t in s.targets] == [0, "b"] and target_ids(s) == [0, "b"]
    p0, p1 = targets_params(s)
    assert list(p0.initial) == [10, 10, 10, 1, 0, 0] and p0.appears == 1 and p0.occlusions == ()
    assert p1.initial is None and p1.appears == 4 and p1.occlusions == ((6, 8),)
    assert p0.draw_speed == p1.draw_speed == s.filter.birth_speed


def test_the_first_of_the_list_is_the_scenarios_one_target():
    s = _two()
    assert s.target.model_dump() == s.targets[0].model_dump(exclude={"id"})


def test_a_list_round_trips_through_its_yaml(tmp_path):
    s = _two()
    text = scenario_to_yaml(s)
    data = yaml.safe_load(text)
    assert "target" not in data and [t["id"] for t in data["targets"]] == [0, "b"]
    f = tmp_path / "s.yaml"
    f.write_text(text)
    assert load_scenario(str(f)) == s


@given(st.lists(st.from_regex(r"[-+]?[0-9]{1,3}(\.[0-9]{0,2})?[eE][-+]?[0-9]{1,2}", fullmatch=True), min_size=1,
                max_size=3, unique_by=str.lower))
@settings(max_examples=30, deadline=None)
def test_texts_that_read_as_numbers_keep_their_quotes_in_the_yaml(tmp_path_factory, ids):
    # scenario.yaml wrote the id "1e3" bare, which the loader reads as the number 1000: the file
    # a run writes could not be fed back, or clashed with an id 1000
    name = ids[0].lstrip("+-")  # a name starts with a digit or a letter
    s = load_scenario("swarm-3", [f"name={name!r}", "targets=" + str([{"id": i} for i in ids] + [{"id": 1000}])])
    f = tmp_path_factory.mktemp("yaml") / "s.yaml"
    f.write_text(scenario_to_yaml(s))
    back = load_scenario(str(f))
    assert back == s and back.name == name and [t.id for t in back.targets] == ids + [1000]


def test_a_list_of_one_gives_the_same_target_as_target():
    one = load_scenario("paper-fig3")
    listed = load_scenario("paper-fig3", ["target=null", "targets=[{initial: [20, 20, 20, 1.5, 2.0, 1.7], occlusions: [[14, 17]]}]"])
    _same_params(vars(targets_params(listed)[0]), vars(target_params(one)))


def test_ids_one_and_text_one_are_the_same_id():
    with pytest.raises(ConfigError, match=r"targets: targets\[0\] and targets\[1\] have the same id"):
        validate_scenario({"targets": [{"id": 1}, {"id": "1"}]})


@pytest.mark.parametrize(
    "data, words",
    [
        ({"targets": []}, ["targets:", "empty"]),
        ({"targets": [{"id": 3}, {}, {"id": 3}]}, ["targets:", "targets[0] and targets[2]", "same id 3"]),
        ({"targets": [{"id": "a"}, {}, {"id": 1}]}, ["targets:", "same id 1"]),
        ({"targets": [{}, {"initial": [10, 10, 120, 0, 0, 0]}]}, ["targets[1].initial", "outside the `area`"]),
        ({"targets": [{"id": True}]}, ["targets.0.id", "integer or a text"]),
        ({"targets": [{"id": 2.5}]}, ["targets.0.id", "integer or a text"]),
        ({"targets": [{"id": " a"}]}, ["targets.0.id", "1 to 100 characters"]),
        ({"targets": [{"id": "a"}, {"id": "a\x00"}]}, ["targets.1.id", "non-printing characters"]),  # merged in the log
        ({"targets": [{"id": "a\nb"}]}, ["targets.0.id", "non-printing characters"]),
        ({"targets": [{"id": "a\x85b"}]}, ["targets.0.id", "non-printing characters"]),
        ({"targets": [{"id": "a\u2028b"}]}, ["targets.0.id", "non-printing characters"]),
        ({"targets": [{"id": 2**70}]}, ["targets.0.id", "2^63"]),
        ({"targets": [{"appear": 3}]}, ["targets.0.appear", "unknown key"]),
        ({"targets": [{"appears": 5, "disappears": 3}]}, ["targets.0", "disappears must be >= appears"]),
        ({"targets": [{}] * 65}, ["targets:", "at most 64"]),
        ({"targets": [{}], "target": {"appears": 2}}, ["either `target`", "not both"]),
        ({"targets": {"id": 1}}, ["targets:", "valid list"]),
    ],
)
def test_bad_target_lists_are_refused_in_one_line_naming_the_key(data, words):
    with pytest.raises(ConfigError) as err:
        validate_scenario(data)
    line = str(err.value)
    assert "\n" not in line and all(w in line for w in words), line


def test_target_null_sets_the_one_target_aside_only_beside_a_list():
    assert validate_scenario({"target": None, "targets": [{"id": "x"}]}).target_list[0].id == "x"
    with pytest.raises(ConfigError, match="target:"):
        validate_scenario({"target": None})


def test_a_default_scenario_accepts_a_list_without_target():
    s = Scenario(targets=[{"id": "only"}])
    assert s.target_list[0].id == "only" and s.target == Scenario().target


@pytest.mark.parametrize(
    "item, key",
    [
        ("targets=[]", "targets"),
        ("targets=[{id: 1}, {id: 1}]", "targets"),
        ("targets=[{initial: [150, 0, 0, 0, 0, 0]}]", "targets[0].initial"),
        (TWO + " --set control.at_least=4", "control.at_least"),
    ],
)
def test_the_command_line_refuses_bad_targets_with_exit_2(item, key):
    sets = [a for x in ["target=null", *item.split(" --set ")] for a in ("--set", x)]
    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", "paper-fig3", *sets], capture_output=True, text=True)
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(lines) == 1 and key in lines[0], r.stderr


def test_each_listed_target_warns_under_its_own_key():
    from trackjam.config.warnings import scenario_warnings

    s = _two("targets=[{appears: 3}, {appears: 31, occlusions: [[2, 3], [29, 40]]}]")
    lines = scenario_warnings(s)
    assert len(lines) == 2 and lines[0].startswith("targets[1].appears: step 31") and "never appears" in lines[0]
    assert lines[1] == "targets[1].occlusions: [29, 40] reach past the last step (30)"
    one = scenario_warnings(load_scenario("paper-fig3", ["target.appears=31"]))
    assert one == ["target.appears: step 31 comes after the last step (30); the target never appears"]


LISTED = yaml.safe_load(scenario_to_yaml(_two()))
TARGET_PATHS = sorted({p for p in value_paths(LISTED) if p[0] == "targets"}, key=str)
ODD = [1e300, -1, 0, 0.5, float("nan"), float("inf"), 10**30, True, None, "", "abc", [], [1, 2], {}, {"x": 1}, 3, "b", 0]


@settings(max_examples=300, deadline=None)
@given(path=st.sampled_from(TARGET_PATHS), value=st.sampled_from(ODD))
def test_an_odd_value_in_a_target_list_is_refused_in_one_line_or_accepted(path, value):
    data = yaml.safe_load(yaml.safe_dump(LISTED))
    node = data
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value
    try:
        s = validate_scenario(data)
    except ConfigError as err:
        assert "\n" not in str(err) and str(err)
        return
    assert len(targets_params(s)) == len(target_ids(s)) == len(s.target_list)
    assert len({str(i) for i in target_ids(s)}) == len(s.target_list)


def test_an_occlusion_after_the_last_step_is_said_to_be_none_of_this_run():
    from trackjam.config.warnings import scenario_warnings

    lines = scenario_warnings(load_scenario("paper-fig3", ["steps=5", "target.occlusions=[[3, 8], [14, 17], [20, 21]]"]))
    assert "target.occlusions: [3, 8] reach past the last step (5)" in lines
    assert "target.occlusions: [14, 17], [20, 21] start after the last step (5), so this run has none of them" in lines
    assert not [w for w in scenario_warnings(load_scenario("paper-fig3")) if "occlusions" in w]
