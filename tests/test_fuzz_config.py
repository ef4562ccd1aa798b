"""Fuzzing the configuration: one value of the resolved paper-fig3 replaced by something huge,
tiny, negative, NaN, infinite or of the wrong type. Validation either refuses it with one line
(a ConfigError) or accepts it, and then a short run gives finite outputs. Nothing else: no
traceback, no hang, no NaN from an accepted scenario."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from trackjam.config import load_scenario, scenario_to_dict, validate_scenario
from trackjam.errors import ConfigError
from config_paths import value_paths

SMALL = ["steps=3", "filter.particles=200", "filter.birth_particles=50", "control.grasp.samples=50", "control.grasp.iterations=2"]
BASE = scenario_to_dict(load_scenario("paper-fig3", SMALL))

# after acceptance the run is kept short: a mutation may legally ask for a long or heavy run
SHORT = {
    ("steps",): 3, ("filter", "particles"): 200, ("filter", "birth_particles"): 100, ("control", "samples"): 50,
    ("control", "iterations"): 2, ("sensor", "clutter_rate"): 20.0, ("agents", "n_inclination"): 8,
    ("agents", "n_azimuth"): 8, ("control", "time_limit_s"): 0.2,
}

ODD_VALUES = [
    1e300, -1e300, 1e9, -1, 0, 0.0, -0.0, 1e-300, 5e-324, float("nan"), float("inf"), -float("inf"),
    10**30, 2**63, True, False, None, "abc", "", "1e3", [], [1, 2], {}, {"x": 1}, 179.999999, 1000, 0.5, 3,
]


PATHS = sorted(set(value_paths(BASE)), key=str)


def _copy(node):
    if isinstance(node, dict):
        return {k: _copy(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_copy(v) for v in node]
    return node


def _set(data, path, value):
    node = data
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value


def _shorten(data):
    for path, cap in SHORT.items():
        node = data
        for p in path[:-1]:
            node = node.get(p) if isinstance(node, dict) else None
        if isinstance(node, dict) and isinstance(node.get(path[-1]), (int, float)):
            node[path[-1]] = min(node[path[-1]], cap)


FINITE_STEP_COLUMNS = ["existence", "ospa", "target_received_w"]
FINITE_AGENT_COLUMNS = ["x", "y", "z", "power_w", "p_d", "existence", "interference_w", "to_target_w"]


def test_the_paths_cover_every_key_of_the_scenario():
    keys = {".".join(str(p) for p in path) for path in PATHS}
    assert {"antenna.power_levels_db.1", "area.high.0", "filter.cue.position_std", "steps"} <= keys
    assert len(PATHS) > 60


@settings(max_examples=80, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(path=st.sampled_from(PATHS), value=st.one_of(st.sampled_from(ODD_VALUES), st.floats(), st.integers()))
def test_one_mutated_value_is_refused_in_one_line_or_runs_finite(path, value):
    data = _copy(BASE)
    _set(data, path, value)
    try:
        s = validate_scenario(data, "mutant")
    except ConfigError as err:
        msg = str(err)
        assert msg and "\n" not in msg and len(msg) < 600
        return
    _shorten(data)
    s = validate_scenario(data, "mutant, shortened")

    from trackjam.simulation.loop import simulate

    r = simulate(s)
    for col in FINITE_STEP_COLUMNS:
        assert np.all(np.isfinite(np.asarray(r.steps[col], dtype=float))), (path, value, col)
    for col in FINITE_AGENT_COLUMNS:
        assert np.all(np.isfinite(np.asarray(r.agents[col], dtype=float))), (path, value, col)
    for key, v in r.summary.items():
        if isinstance(v, float):
            assert math.isfinite(v), (path, value, key)


@pytest.mark.parametrize(
    "overrides",
    [
        ["area.low=[-1e5, -1e5, -1e5]", "area.high=[1e5, 1e5, 1e5]", "antenna.height=1e5", "filter.cue.position_std=1e5"],
        ["antenna.opening_angle_deg=170", "sensor.noise_std=[1e4, 3.141592653589793, 3.141592653589793]"],
        ["antenna.opening_angle_deg=0.1", "sensor.noise_std=[1e-3, 1e-6, 1e-6]", "filter.birth=measurement"],
        ["antenna.power_levels_db=[off, -200, 60]", "antenna.interference_limit_db=60", "target.response={threshold_db: -200}"],
        ["filter.birth_speed=1000", "target.accel_var=1e4", "target.initial=[20, 20, 20, 1000, -1000, 1000]"],
    ],
)
def test_runs_at_the_bounds_stay_finite(overrides):
    from trackjam.simulation.loop import simulate

    r = simulate(load_scenario("paper-fig3", SMALL + overrides))
    for col in FINITE_STEP_COLUMNS:
        assert np.all(np.isfinite(r.steps[col])), col
    for col in FINITE_AGENT_COLUMNS:
        assert np.all(np.isfinite(r.agents[col])), col


@pytest.mark.parametrize("key", ["filter.birth_speed", "target.accel_var", "sensor.clutter_rate", "filter.accel_var"])
def test_negative_zero_is_zero(key):
    from trackjam.simulation.loop import simulate

    s = load_scenario("paper-fig3", SMALL + [f"{key}=-0.0"])
    section, name = key.split(".")
    assert math.copysign(1.0, getattr(getattr(s, section), name)) == 1.0
    assert np.all(np.isfinite(simulate(s).steps["existence"]))
