"""The library's pieces used alone refuse bad arguments with one exception naming the argument
(a fuzz hunt of the Python API: a kernel read past a short array, NaN became 0, a sample count
of 10^12 ran a compiled loop no Ctrl-C stops, an empty array passed for the empty set)."""

import dataclasses

import numpy as np
import pytest

from trackjam.control.solve import SolverOptions, build_problem, solve
from trackjam.estimation.bernoulli import BernoulliFilter, FilterParams
from trackjam.metrics.ospa import ospa
from trackjam.radio.antenna import AntennaModel
from trackjam.world.moves import displacement_set

ANTENNA = dict(height=40.0, half_angle=np.radians(40), r0=6.0, n_e=2.0, p_d_max=0.95,
               levels_w=np.array([0.0, 1e-5, 0.2, 1.12]), delta_w=1e-4)


def _filter_params(**changed) -> FilterParams:
    base = dict(birth_prob=0.02, survival_prob=0.98, particles=200, birth_particles=50, birth="uniform", birth_mix=0.5,
                measurement_birth_speed=1.0, birth_speed=3.0, accel_var=0.5, walls="reflect",
                low=np.zeros(3), high=np.full(3, 100.0), noise_std=np.array([0.8, 0.0628, 0.0628]), clutter_rate=3.0)
    return FilterParams(**(base | changed))


@pytest.mark.parametrize("changed, error, words", [
    ({"half_angle": np.radians(100)}, ValueError, "half_angle: must be a finite number in (0, 1.48353]"),
    ({"levels_w": np.zeros(3)}, ValueError, "levels_w: must start at 0 (off) and increase"),
    ({"levels_w": np.array([])}, ValueError, "levels_w: expected a vector of at least 2 entries"),
    ({"levels_w": np.array([0.0, 1.0, 0.5])}, ValueError, "levels_w: must start at 0 (off) and increase"),
    ({"r0": 0.0}, ValueError, "r0: must be a finite number in (0, inf)"),
    ({"r0": float("nan")}, ValueError, "r0: must be a finite number"),
    ({"n_e": -2.0}, ValueError, "n_e: must be a finite number in (0, 10]"),
    ({"p_d_max": 2.0}, ValueError, "p_d_max: must be a finite number in [0, 1]"),
    ({"height": "40"}, TypeError, "height: expected a number, got str"),
    ({"delta_w": True}, TypeError, "delta_w: expected a number, got bool"),
])
def test_an_antenna_model_refuses_what_the_configuration_would(changed, error, words):
    with pytest.raises(error) as err:
        AntennaModel(**(ANTENNA | changed))
    assert str(err.value).startswith(words)


@pytest.mark.parametrize("changed, words", [
    ({"noise_std": np.array([0.8])}, "noise_std: expected a vector of 3 entries"),  # the kernel read past it
    ({"noise_std": np.array([0.8, 0.0, 0.06])}, "noise_std: the standard deviations must be > 0"),
    ({"particles": 1}, "particles: must lie in [10, 10000000]"),
    ({"particles": 10**13}, "particles: must lie in [10, 10000000]"),  # it tried to allocate 437 TiB
    ({"birth_particles": 0}, "birth_particles: must lie in [1, 10000000]"),
    ({"survival_prob": float("nan")}, "survival_prob: must be a finite number in [0, 1]"),
    ({"birth_prob": 2.0}, "birth_prob: must be a finite number in [0, 1]"),
    ({"accel_var": -1.0}, "accel_var: must be a finite number in [0, inf)"),
    ({"walls": "bounce"}, "walls: expected 'reflect' or 'none'"),  # behaved as "none"
    ({"birth": "gauss"}, "birth: expected 'uniform', 'measurement' or 'mixed'"),
    ({"low": np.full(3, 100.0)}, "low, high: the area's low corner must lie below its high one"),
    ({"high": np.array([100.0, 100.0, np.inf])}, "high: must be finite"),
    ({"visibility": (2.0, 0.1)}, "visibility hide: must be a finite number in [0, 1]"),
    ({"clutter_rate": -1.0}, "clutter_rate: must be a finite number in [0, 1000]"),
])
def test_filter_params_refuse_what_the_configuration_would(changed, words):
    with pytest.raises((ValueError, TypeError)) as err:
        _filter_params(**changed)
    assert str(err.value).startswith(words)


def test_the_filter_params_of_every_preset_pass():
    import trackjam
    from trackjam.simulation.build import filter_params

    for name in ("paper-fig3", "pursuit", "swarm-3", "paper-fig3-literal"):
        assert isinstance(filter_params(trackjam.load_scenario(name)), FilterParams)
    f = BernoulliFilter(_filter_params(), AntennaModel(**ANTENNA), np.random.default_rng(1))  # legal edge: it runs
    f.predict()
    f.update(np.zeros((0, 3)), np.full(3, 30.0), np.full(3, 20.0), 1.12)


@pytest.mark.parametrize("option, value, words", [
    ("samples", 10**12, "samples: must lie in [1, 100000000]"),  # GRASP's compiled loop ran for hours
    ("samples", 0, "samples: must lie in [1, 100000000]"),
    ("iterations", -1, "iterations: must lie in [1, 1000000]"),
    ("neighbours", 10**9, "neighbours: must lie in [2, 1000]"),  # it tried to allocate 1.7 TiB
    ("threads", 0, "threads: must lie in [1, 1024]"),
    ("time_limit_s", float("nan"), "time_limit_s: must be a finite number in (0, 3600]"),
    ("node_limit", 2.5, "node_limit: expected a whole number in [0, 1000000000000]"),
    ("samples", True, "samples: expected a whole number"),
])
def test_solve_refuses_options_past_the_configurations_bounds(option, value, words):
    with pytest.raises((ValueError, TypeError)) as err:
        SolverOptions(**{option: value})
    assert str(err.value).startswith(words)
    problem = build_problem(np.array([[30.0, 30, 30], [20, 10, 10], [10, 15, 15]]), np.full(3, 20.0),
                            displacement_set([1.0, 3.0, 5.0], 8, 8), AntennaModel(**ANTENNA), np.zeros(3),
                            np.full(3, 100.0), 2, True)
    with pytest.raises((ValueError, TypeError)):
        solve(problem, "grasp", [np.random.default_rng(k) for k in range(3)], **{option: value})


@pytest.mark.parametrize("args, words", [
    (([1.0], 10**6, 10**6), "n_inclination: must lie in [1, 360]"),  # it ran for minutes
    (([1.0], 0, 8), "n_inclination: must lie in [1, 360]"),  # ZeroDivisionError
    (([1.0], 8, 2.5), "n_azimuth: expected a whole number"),
    (([np.nan], 8, 8), "radial_steps: must be finite"),
    (([-1.0], 8, 8), "radial_steps: expected 1 to 32 step lengths in (0, 10000] m"),
    (([], 8, 8), "radial_steps: expected 1 to 32 step lengths"),
    (([True], 8, 8), "radial_steps: expected numbers, got list [True]"),
    (([1.0, True], 8, 8), "radial_steps: expected numbers, got a bool among them"),
])
def test_displacement_set_refuses_what_the_configuration_would(args, words):
    with pytest.raises((ValueError, TypeError)) as err:
        displacement_set(*args)
    assert str(err.value).startswith(words)


def test_displacement_set_still_gives_the_papers_79_and_table_is_11():
    assert displacement_set([1, 3, 5], 8, 8).shape == (79, 3)
    assert displacement_set(np.array([3.0]), 4, 8).shape == (11, 3)


@pytest.mark.parametrize("truth, estimate, c, words", [
    (np.zeros((0, 3)), [4.0, 6.0, 3.0], 10.0, "truth: expected a vector of at least 3 entries"),  # gave 0
    ([1.0, np.nan, 0.0], [4.0, 6.0, 3.0], 10.0, "truth: must be finite"),
    ([1.0, 2.0, 3.0], [[1.0, 2.0, 3.0], [50, 50, 50]], 10.0, "estimate: expected a vector"),
    ([1.0, 2.0], [4.0, 6.0, 3.0], 10.0, "truth: expected a vector of at least 3 entries"),
    ([1.0, 2.0, 3.0], None, float("nan"), "c: must be a finite number"),
    ([1.0, 2.0, 3.0], None, True, "c: expected a number, got bool"),
])
def test_ospa_refuses_what_is_not_a_position_or_a_cut_off(truth, estimate, c, words):
    with pytest.raises((ValueError, TypeError)) as err:
        ospa(truth, estimate, c=c)
    assert str(err.value).startswith(words)


def test_ospa_keeps_its_closed_forms():
    assert ospa(None, None) == 0.0 and ospa(None, [1, 2, 3]) == 10.0 and ospa([1, 2, 3], None, c=4) == 4.0
    assert ospa([0, 0, 0], [3, 4, 0]) == 5.0 and ospa([0, 0, 0, 9, 9, 9], [3, 4, 0]) == 5.0
    assert ospa([0, 0, 0], [30, 40, 0]) == 10.0


def test_a_hand_built_antenna_can_still_be_replaced_field_by_field():
    a = AntennaModel(**ANTENNA)
    with pytest.raises(ValueError, match="^levels_w: must start at 0"):
        dataclasses.replace(a, levels_w=a.levels_w[1:])


class _BytesPath:  # a path-like whose path is bytes
    def __fspath__(self):
        return b"/tmp/x"


@pytest.mark.parametrize("value, error, words", [
    (None, TypeError, r"^p: expected a file's path as text, got NoneType None$"),
    (5, TypeError, r"^p: expected a file's path as text, got int 5$"),
    (b"/tmp/x", TypeError, r"^p: expected a file's path as text, got bytes b'/tmp/x'$"),
    (_BytesPath(), TypeError, r"^p: expected a file's path as text, got _BytesPath"),
    ("", ValueError, r"^p: expected a file's path, got an empty text$"),
    ("a\x00b", ValueError, r"^p: holds a NUL character, which no path may: 'a\\x00b'$"),
])
def test_text_path_refuses_what_no_path_may_be(value, error, words):
    from trackjam.arguments import text_path

    with pytest.raises(error, match=words):
        text_path("p", value)


def test_text_path_gives_the_text_of_a_path():
    from pathlib import Path

    from trackjam.arguments import text_path

    assert text_path("p", Path("/tmp/a b")) == "/tmp/a b" and text_path("p", "r.html") == "r.html"


@pytest.mark.parametrize(("value", "expected"), [
    ([True, False], [True, False]), ([1, 0, 1], [True, False, True]), (np.array([0, 1], np.uint8), [False, True]),
    ([], []), (np.zeros(0), []), ([2, 0], None), ([1.0, 0.0], None), (["a"], None),
])
def test_flags_takes_booleans_or_0_and_1_only(value, expected):
    from trackjam.arguments import flags

    got = flags(value)
    assert (got is None) if expected is None else (got.dtype == bool and got.tolist() == expected)
