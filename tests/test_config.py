"""The scenario configuration: presets, files, overrides and one-line errors."""

import math
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest

from trackjam.config import (
    Scenario,
    load_scenario,
    preset_names,
    scenario_to_yaml,
    validate_scenario,
)
from trackjam.errors import ConfigError
from trackjam.simulation.build import antenna_model


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
        ("filter.cue.velocity=fast", "filter.cue.velocity", "'zero' or 'target'"),
        ("steps=abc", "steps", "integer"),
        ("antenna.height=-3", "antenna.height", "greater than 0"),
        ("antenna.opening_angle_deg=180", "antenna.opening_angle_deg", "[0.1, 170]"),
        ("antenna.power_levels_db=[]", "antenna.power_levels_db", "at least 1"),
        ("antenna.r0=.nan", "antenna.r0", "finite"),
        ("antenna.power_levels_db=[off, .nan]", "antenna.power_levels_db", "finite"),
        ("antenna.power_levels_db=[off, 0, -7]", "antenna.power_levels_db", "increasing"),
        ("antenna.power_levels_db=[-7, 0]", "antenna.power_levels_db", "must be off"),
        ("antenna.power_levels_db=[off]", "antenna.power_levels_db", "at least one"),
        ("control.at_least=4", "control.at_least", "exceeds"),
        ("agents.initial=[[200, 0, 0], [1, 1, 1], [2, 2, 2]]", "agents.initial[0]", "outside the `area` [0, 0, 0] to [100, 100, 100]"),
        ("sensor.clutter_rate=-1", "sensor.clutter_rate", "greater than or equal to 0"),
        ("control.solver=magic", "control.solver", "greedy"),
        ("filter.visibility.hide=1.5", "filter.visibility.hide", "less than or equal to 1"),
        ("filter.visibility={hide: 0.1}", "filter.visibility.reappear", "required"),
        ("fusion.report_spread=0", "fusion.report_spread", "greater than 0"),
        ("control.belief_spread=-2", "control.belief_spread", "greater than 0"),
        ("control.belief_spread=.nan", "control.belief_spread", "finite"),
        ("filter.mode.radius=-5", "filter.mode.radius", "greater than 0"),
        ("filter.mode={radius: 5, mass: 0}", "filter.mode.mass", "greater than 0"),
        ("filter.mode={mass: 1.5}", "filter.mode.mass", "less than or equal to 1"),
        ("filter.mode={radius: 5, weight: 0.2}", "filter.mode.weight", "unknown key"),
        ("fusion.share=gossip", "fusion.share", "posteriors"),
        ("filter.response.steps=0", "filter.response.steps", "greater than or equal to 1"),
        ("filter.response={action: fly}", "filter.response.action", "'land', 'hover' or 'return'"),
        ("filter.response.speed=-1", "filter.response.speed", "greater than 0"),
        ("filter.response.threshold_db=.nan", "filter.response.threshold_db", "finite"),
        ("filter.response={action: land, delay: 2}", "filter.response.delay", "unknown key"),
        ("filter.response.hedge=1.5", "filter.response.hedge", "less than or equal to 1"),
        ("target.response={action: land, hedge: 0.2}", "target.response.hedge", "unknown key"),
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


@pytest.mark.parametrize(
    "override, key, words",
    [
        ("antenna.power_levels_db=[off, 5000]", "antenna.power_levels_db", "outside [-200, 60] dBW"),
        ("antenna.interference_limit_db=5000", "antenna.interference_limit_db", "less than or equal to 60"),
        ("target.response={threshold_db: 5000}", "target.response.threshold_db", "less than or equal to 60"),
        ("filter.birth_speed=1e300", "filter.birth_speed", "less than or equal to 1000"),
        ("filter.cue.position_std=1e300", "filter.cue.position_std", "less than or equal to 100000"),
        ("area.high=[1e300, 1e300, 1e300]", "area.high", "less than or equal to 100000"),
        ("antenna.height=1e300", "antenna.height", "less than or equal to 100000"),
        ("sensor.noise_std=[1e300, 1e300, 1e300]", "sensor.noise_std", "less than or equal to"),
        ("antenna.opening_angle_deg=179.999999", "antenna.opening_angle_deg", "[0.1, 170]"),
        ("agents.n_inclination=1000", "agents.n_inclination", "less than or equal to 360"),
        ("sensor.clutter_rate=1e6", "sensor.clutter_rate", "less than or equal to 1000"),
        ("filter.particles=1e9", "filter.particles", "less than or equal to 10000000"),
        ("control.grasp.samples=1e9", "control.grasp.samples", "less than or equal to 100000000"),
        ("control.grasp.iterations=1e7", "control.grasp.iterations", "less than or equal to 1000000"),
        ("control.grasp.samples=1e7", "control.grasp.samples", "past the cap"),
        ("steps=true", "steps", "must be an integer"),
        ("steps='30'", "steps", "must be an integer"),
        ("steps=2.5", "steps", "integer"),
        ("antenna.height=true", "antenna.height", "must be a number"),
        ("control.constraints=1", "control.constraints", "boolean"),
        ("seed=-1", "seed", "greater than or equal to 0"),
        ("area.high=[100, 100, 0.5]", "area", "at least 1 m"),
        ("name='[/oops]'", "name", "not a safe folder name"),
        ("name=../../escaped", "name", "not a safe folder name"),
        ("name=/tmp/abs", "name", "not a safe folder name"),
        (f"name={'x' * 300}", "name", "not a safe folder name"),
    ],
)
def test_values_past_their_physical_bounds_are_refused_in_one_line(override, key, words):
    with pytest.raises(ConfigError) as info:
        load_scenario("paper-fig3", [override])
    msg = str(info.value)
    assert "\n" not in msg and len(msg) < 300
    assert f"{key}" in msg and words in msg, msg
    assert msg.startswith(f"--set {override[:20]}")  # blamed on the --set, not on the preset


@pytest.mark.parametrize(
    "override, message",
    [
        # pydantic said "agents.initial.1.2: Field required"
        ("agents.initial=[[10,10,10],[10,10]]", "agents.initial.1: expected 3 coordinates (x, y, z), got 2"),
        ("agents.initial=[[10,10,10,4]]", "agents.initial.0: expected 3 coordinates (x, y, z), got 4"),
        ("agents.initial_aim=[1]", "agents.initial_aim: expected 3 coordinates (x, y, z), got 1"),
        ("area.low=[0,0]", "area.low: expected 3 coordinates (x, y, z), got 2"),
        ("area.high=[100,100,100,100]", "area.high: expected 3 coordinates (x, y, z), got 4"),
        ("target.initial=[1,2,3]", "target.initial: expected 6 values (x, y, z, vx, vy, vz), got 3"),
        ("target.response={home: [1,2]}", "target.response.home: expected 3 coordinates (x, y, z), got 2"),
        ("sensor.noise_std=[1]", "sensor.noise_std: expected 3 standard deviations (range, azimuth, inclination), got 1"),
        ("target.occlusions=[[3]]", "target.occlusions.0: expected 2 steps (first, last), got 1"),
        ("targets=[{initial: [1,2]}]", "targets.0.initial: expected 6 values (x, y, z, vx, vy, vz), got 2"),
    ],
)
def test_a_vector_of_the_wrong_length_says_how_many_values_it_needs(override, message):
    with pytest.raises(ConfigError) as info:
        load_scenario("paper-fig3", [override])
    assert str(info.value) == f"--set {override}: {message}"


def test_a_float_that_is_an_integer_is_read_as_one_and_written_back_as_an_int():
    s = load_scenario("paper-fig3", ["steps=5.0", "filter.particles=2e3"])
    assert s.steps == 5 and s.filter.particles == 2000 and type(s.filter.particles) is int


def test_numpy_integers_are_integers():
    assert load_scenario("paper-fig3", seed=np.uint64(2**63 - 1), steps=np.int64(3)).seed == 2**63 - 1


def test_a_keyword_of_load_scenario_is_blamed_not_the_preset():
    with pytest.raises(ConfigError) as e:
        load_scenario("paper-fig3", ["seed=3"], steps="x", control__solver="exact")
    assert str(e.value) == "load_scenario(steps='x'): steps: must be an integer, got str 'x'"
    with pytest.raises(ConfigError, match=r"^--set steps=x: steps: must be an integer"):
        load_scenario("paper-fig3", ["steps=x"])
    with pytest.raises(ConfigError, match=r"^preset paper-fig3: steps: must be an integer"):
        validate_scenario({**load_scenario("paper-fig3").model_dump(mode="json"), "steps": "x"}, "preset paper-fig3")


@pytest.mark.parametrize(
    "value, shown",
    [
        (10**400, "an integer of 401 digits"),
        (Decimal("NaN"), "NaN"),
        (Decimal("1e500"), "1E+500"),
        (np.float32("nan"), "nan"),
        (-(10**309), "an integer of 310 digits"),
    ],
)
def test_a_number_that_is_no_finite_float_is_named_as_such(value, shown):
    with pytest.raises(ConfigError) as e:
        load_scenario("paper-fig3", antenna__r0=value)
    assert str(e.value).endswith(f"antenna.r0: must be a finite number, got {shown}")


def test_other_kinds_of_real_number_are_read_as_floats():
    s = load_scenario("paper-fig3", antenna__r0=Fraction(13, 2), sensor__noise_std=[Decimal("0.5"), 0.1, np.int64(1)])
    assert s.antenna.r0 == 6.5 and type(s.antenna.r0) is float
    assert s.sensor.noise_std == (0.5, 0.1, 1.0)


def test_the_bounds_themselves_are_accepted():
    s = load_scenario(
        "paper-fig3",
        [
            "area.low=[-1e5, -1e5, -1e5]", "area.high=[1e5, 1e5, 1e5]", "antenna.height=1e5",
            "antenna.opening_angle_deg=170", "antenna.power_levels_db=[off, -200, 60]",
            "antenna.interference_limit_db=60", "sensor.noise_std=[1e4, 3.141592653589793, 1e-6]",
            "filter.birth_speed=1000", "agents.n_inclination=360", "control.grasp.iterations=1",
        ],
    )
    assert s.antenna.levels_w == pytest.approx([0.0, 1e-20, 1e6])


def test_displacement_bound_covers_eq3_and_the_table_estimate_bounds_the_problems_arrays():
    from trackjam.config.limits import candidates_bound, estimate
    from trackjam.control.problem import build_problem
    from trackjam.world.moves import displacement_set

    for radial in ([3.0], [1.0, 3.0, 5.0]):
        for n_phi in range(1, 11):
            for n_theta in range(1, 11):
                assert len(displacement_set(radial, n_phi, n_theta)) == candidates_bound(len(radial), n_phi, n_theta)
    assert candidates_bound(3, 8, 8) == 79 and candidates_bound(1, 4, 8) == 11  # the paper's two sets
    s = load_scenario("paper-fig3", ["agents.radial_steps=[1.0, 2.0]"])
    D = displacement_set(s.agents.radial_steps, s.agents.n_inclination, s.agents.n_azimuth)
    problem = build_problem(
        np.asarray(s.agents.initial, float), np.asarray(s.target.initial[:3], float), D,
        antenna_model(s), s.area.low, s.area.high, 2, True,
    )
    tables = problem.gain.nbytes + problem.p_d.nbytes
    estimated = estimate(s)["memory_tables"][0]
    assert tables == estimated  # every agent far from the walls keeps all its candidates


def test_a_run_too_big_for_the_machine_is_refused_naming_the_key_that_grew_it(monkeypatch):
    from trackjam.config import limits

    monkeypatch.setattr(limits, "memory_budget", lambda: 50e6)
    assert load_scenario("paper-fig3")  # about 7.5 MB
    with pytest.raises(ConfigError, match=r"^--set agents.n_azimuth=128: agents.n_azimuth: a run would hold"):
        load_scenario("paper-fig3", ["agents.n_azimuth=128"])
    with pytest.raises(ConfigError, match=r"filter.particles: a run would hold about .* more than half"):
        load_scenario("paper-fig3", ["filter.particles=200000"])
    with pytest.raises(ConfigError, match=r"sensor.clutter_rate: a run would hold"):
        load_scenario("paper-fig3", ["sensor.clutter_rate=1000", "steps=1000"])


def test_the_filters_work_per_step_is_capped():
    with pytest.raises(ConfigError, match=r"sensor.clutter_rate: one step would take about 3.6e\+09 operations \(filter\)"):
        load_scenario("paper-fig3", ["filter.particles=1e6", "sensor.clutter_rate=1000"])


def test_shared_scans_multiply_the_filters_work_by_the_team():
    """With fusion.share: scans each of N agents updates on N scans: 64 agents in heavy clutter
    took about 35 s a step while the check counted one scan per agent."""
    from trackjam.config import limits

    agents = f"agents.initial={[[50.0, 50.0, 10.0 + i] for i in range(64)]}"
    base = ["control.solver=exact", agents, "sensor.clutter_rate=100"]
    alone = limits.estimate(load_scenario("paper-fig3", base))["work_filter"][0]
    assert alone < 1e9
    with pytest.raises(ConfigError, match=r"one step would take about .* operations \(filter\)"):
        load_scenario("paper-fig3", [*base, "fusion.share=scans"])
    small = load_scenario("pursuit")
    assert limits.estimate(small)["work_filter"][0] == 3 * limits.estimate(
        load_scenario("pursuit", ["fusion.share=posteriors"]))["work_filter"][0]


def test_grasp_work_is_checked_only_for_grasp():
    with pytest.raises(ConfigError, match="control.grasp.iterations: one step would take about"):
        load_scenario("paper-fig3", ["control.grasp.iterations=100000"])
    assert load_scenario("paper-fig3", ["control.grasp.iterations=100000", "control.solver=exact"])


def test_messages_in_flight_count_in_the_memory_check(monkeypatch):
    """comms.delay_steps holds every message of delay_steps steps: 48 agents at the 1000-step
    bound is gigabytes, which the check must see; the estimate bounds what a short run holds."""
    import tracemalloc

    from trackjam.config import limits
    from trackjam.simulation.engine import Simulation

    # (48 agents, each planning from its own inbox under the delay, and comms.stale: drop, so
    # that they fuse one inbox a step: 64 agents, or coasting, are past the work cap)
    big = load_scenario("paper-fig3", ["comms.delay_steps=1000", "steps=1005", "control.solver=exact",
                                       "comms.stale=drop",
                                       f"agents.initial={[[50.0, 50.0, 10.0 + i] for i in range(48)]}"])
    assert limits.estimate(big)["memory_messages"][0] > 1e9
    assert "memory_messages" not in limits.estimate(load_scenario("paper-fig3"))
    # no message due after the last step is held: a delay past a short run costs what the run does
    short = load_scenario("paper-fig3", ["comms.delay_steps=1000", "steps=5"])
    assert limits.estimate(short)["memory_messages"][0] == pytest.approx(
        limits.estimate(load_scenario("paper-fig3", ["comms.delay_steps=5", "steps=5"]))["memory_messages"][0])
    monkeypatch.setattr(limits, "memory_budget", lambda: 200e6)
    with pytest.raises(ConfigError, match=r"comms.delay_steps: a run would hold about .* of memory"):
        load_scenario("paper-fig3", ["comms.delay_steps=1000", "steps=1005",
                                     f"agents.initial={[[50.0, 50.0, 10.0 + i] for i in range(16)]}"])
    # measured: 8 agents, 20 steps of delay, small filters; the pending messages after 22 steps
    s = load_scenario("paper-fig3", ["comms.delay_steps=20", "steps=60", "filter.particles=200",
                                     "filter.birth_particles=50", "control.solver=exact",
                                     f"agents.initial={[[40.0 + 3 * i, 45.0, 30.0] for i in range(8)]}"])
    sim = Simulation(s)
    sim.step()
    tracemalloc.start()
    try:
        for _ in range(21):
            sim.step()
        held = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert sum(len(waiting) for waiting in sim.team.exchange.pending.values()) == 8 * 7 * 3 * 20
    assert held <= limits.estimate(s)["memory_messages"][0] + 20e6  # the rest of a small run


def test_a_file_on_a_base_preset_is_the_preset_with_the_files_keys_on_top(tmp_path):
    f = tmp_path / "short.yaml"
    f.write_text("base: pursuit\nname: short\nsteps: 12\nfilter: {particles: 5000}\n"
                 "antenna: {power_levels_db: [off, -7]}\n")
    s = load_scenario(f)
    want = load_scenario("pursuit", ["name=short", "steps=12", "filter.particles=5000",
                                     "antenna.power_levels_db=[off, -7]"])
    assert s == want
    assert s.filter.birth_particles == load_scenario("pursuit").filter.birth_particles  # merged, not replaced
    assert s.filter.mode == load_scenario("pursuit").filter.mode and s.control.lead == 0.5


def test_a_base_file_without_a_name_is_scenario_and_toml_takes_base_too(tmp_path):
    f = tmp_path / "t.toml"
    f.write_text('base = "paper-fig3"\n[control]\nsolver = "exact"\n')
    s = load_scenario(f)
    assert s.name == "scenario"
    assert s.model_dump(exclude={"name"}) == load_scenario("paper-fig3", ["control.solver=exact"]).model_dump(
        exclude={"name"})


def test_a_files_targets_replace_its_bases_target_and_the_other_way_round(tmp_path):
    f = tmp_path / "two.yaml"
    f.write_text("base: paper-fig3\ntargets:\n  - {id: a, initial: [20, 20, 20, 1, 1, 1]}\n"
                 "  - {id: b, initial: [60, 60, 60, 0, 0, 0]}\n")
    s = load_scenario(f)
    assert [t.id for t in s.targets] == ["a", "b"]
    g = tmp_path / "one.yaml"
    g.write_text("base: swarm-3\ntarget: {initial: [50, 50, 50, 0, 0, 0]}\n")
    one = load_scenario(g)
    assert one.targets is None and one.target.initial == (50, 50, 50, 0, 0, 0)
    assert one.agents == load_scenario("swarm-3").agents


@pytest.mark.parametrize("base, words", [
    ("pursit", "base: 'pursit' is not a preset (did you mean pursuit?)"),
    ("3", "base: 3 is not a preset;"),
    ("runs/other.yaml", "base: 'runs/other.yaml' is not a preset;"),
    ("", "base: null (no value) is not a preset;"),
])
def test_a_base_that_is_not_a_preset_is_one_error_naming_the_file_and_the_key(tmp_path, base, words):
    f = tmp_path / "b.yaml"
    f.write_text(f"base: {base}\nsteps: 5\n")
    with pytest.raises(ConfigError) as e:
        load_scenario(f)
    assert str(e.value).startswith(f"{f}: {words}") and "paper-fig3" in str(e.value)


def test_base_is_read_from_the_file_alone(tmp_path):
    with pytest.raises(ConfigError, match=r"--set base=pursuit: base: unknown key here \(base, the preset"):
        load_scenario("paper-fig3", ["base=pursuit"])
    f = tmp_path / "nested.yaml"
    f.write_text("base: paper-fig3\nfilter: {base: pursuit}\n")
    with pytest.raises(ConfigError, match=r"filter\.base: unknown key"):
        load_scenario(f)


def test_a_preset_dropped_into_the_folder_may_name_a_base_and_a_loop_of_bases_is_one_error(tmp_path, monkeypatch):
    import types
    from importlib import resources

    from trackjam.config import loading

    real = resources.files("trackjam.presets")
    for name in ("paper-fig3", "pursuit"):
        (tmp_path / f"{name}.yaml").write_text(real.joinpath(f"{name}.yaml").read_text())
    (tmp_path / "mine.yaml").write_text("base: pursuit\nname: mine\nsteps: 9\n")
    (tmp_path / "loop-a.yaml").write_text("base: loop-b\nname: loop-a\n")
    (tmp_path / "loop-b.yaml").write_text("base: loop-a\nname: loop-b\n")
    monkeypatch.setattr(loading, "resources", types.SimpleNamespace(files=lambda package: tmp_path))
    assert load_scenario("mine") == load_scenario("pursuit", ["name=mine", "steps=9"])
    with pytest.raises(ConfigError, match=r"^preset loop-a: base: a loop of bases \(loop-a -> loop-b -> loop-a\)$"):
        load_scenario("loop-a")


@pytest.mark.parametrize("base, text, sets", [
    # the file's `targets: null` (as show-config writes it) is the one target: the preset's, kept
    ("paper-fig3", "targets: null\n", ["targets=null"]),
    # `target: null` beside a base's list sets the one target aside, as it does beside a file's list
    ("swarm-3", "target: null\n", ["target=null"]),
])
def test_a_target_or_targets_given_as_null_keeps_the_bases_other_one(tmp_path, base, text, sets):
    f = tmp_path / "b.yaml"
    f.write_text(f"base: {base}\n{text}")
    assert load_scenario(f).model_dump(exclude={"name"}) == load_scenario(base, sets).model_dump(exclude={"name"})
