"""The scenario configuration: presets, files, overrides and one-line errors."""

import math

import pytest

from trackjam.config import (
    Scenario,
    load_scenario,
    preset_names,
    scenario_to_yaml,
    validate_scenario,
)
from trackjam.errors import ConfigError


def test_paper_fig3_preset_holds_the_papers_settings():
    s = load_scenario("paper-fig3")
    assert "paper-fig3" in preset_names()
    assert s.steps == 30 and s.n_agents == 3
    assert s.target.initial == (20, 20, 20, 1.5, 2.0, 1.7) and s.target.occlusions == [(14, 17)]
    assert s.antenna.levels_w == pytest.approx([0.0, 1e-5, 0.19952623, 1.12201845])
    assert s.antenna.delta_w == pytest.approx(1e-4)
    assert s.sensor.noise_std[1] == pytest.approx(math.pi / 50, rel=1e-6)
    assert s.control.at_least == 2 and s.control.constraints


def test_defaults_are_model_md_read_literally():
    ex = {"name", "target", "sensor"}  # the preset writes pi/50 as 0.0628319, as the issue does
    literal = load_scenario("paper-fig3-literal")
    assert Scenario().model_dump(exclude=ex) == literal.model_dump(exclude=ex)
    assert Scenario().sensor.noise_std == pytest.approx(literal.sensor.noise_std, rel=1e-6)


def test_paper_fig3_differs_from_the_literal_reading_only_by_our_three_choices():
    a = load_scenario("paper-fig3").model_dump(exclude={"name"})
    b = load_scenario("paper-fig3-literal").model_dump(exclude={"name"})
    diff = {(sec, k) for sec in a if isinstance(a[sec], dict) for k in a[sec] if a[sec][k] != b[sec][k]}
    assert diff == {("filter", "cue"), ("fusion", "existence"), ("control", "fallback")}


def test_resolved_yaml_round_trips(tmp_path):
    s = load_scenario("paper-fig3", ["antenna.opening_angle_deg=120"])
    f = tmp_path / "s.yaml"
    f.write_text(scenario_to_yaml(s))
    assert load_scenario(str(f)) == s


def test_toml_files_are_read(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('name = "t"\nsteps = 5\n[antenna]\nopening_angle_deg = 60\n')
    s = load_scenario(str(f))
    assert s.steps == 5 and s.antenna.opening_angle_deg == 60


def test_overrides_are_dotted_and_validated():
    s = load_scenario("paper-fig3", ["antenna.opening_angle_deg=120", "control.solver=exact"], steps=7)
    assert s.antenna.opening_angle_deg == 120 and s.control.solver == "exact" and s.steps == 7


@pytest.mark.parametrize(
    "override, key, words",
    [
        ("antenna.heigth=3", "antenna.heigth", "unknown key"),
        ("steps=abc", "steps", "integer"),
        ("antenna.height=-3", "antenna.height", "greater than 0"),
        ("antenna.opening_angle_deg=180", "antenna.opening_angle_deg", "(0, 180)"),
        ("antenna.power_levels_db=[]", "antenna.power_levels_db", "at least 1"),
        ("antenna.r0=.nan", "antenna.r0", "finite"),
        ("antenna.power_levels_db=[off, .nan]", "antenna.power_levels_db", "finite"),
        ("antenna.power_levels_db=[off, 0, -7]", "antenna.power_levels_db", "increasing"),
        ("antenna.power_levels_db=[-7, 0]", "antenna.power_levels_db", "must be off"),
        ("antenna.power_levels_db=[off]", "antenna.power_levels_db", "at least one"),
        ("control.at_least=4", "control.at_least", "exceeds"),
        ("agents.initial=[[200, 0, 0], [1, 1, 1], [2, 2, 2]]", "agents.initial[0]", "outside the area"),
        ("sensor.clutter_rate=-1", "sensor.clutter_rate", "greater than or equal to 0"),
        ("control.solver=magic", "control.solver", "greedy"),
    ],
)
def test_bad_values_give_one_line_naming_the_key(override, key, words):
    with pytest.raises(ConfigError) as info:
        load_scenario("paper-fig3", [override])
    msg = str(info.value)
    assert "\n" not in msg
    assert key.split("[")[0] in msg and words in msg


def test_missing_file_is_a_clear_error():
    with pytest.raises(ConfigError, match="no such file"):
        load_scenario("does/not/exist.yaml")


def test_a_scenario_must_be_a_mapping():
    with pytest.raises(ConfigError, match="mapping"):
        validate_scenario([1, 2], "x")
