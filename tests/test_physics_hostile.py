"""Physics at the documented bounds of the configuration and just inside them, where a formula
could overflow or degenerate: a huge antenna with a tiny full-gain radius, noise at its floor,
certainty (p_D = 1, p_S = 1, p_B = 1) and impossibility (p_D = 0, p_S = 0), no power, a single
agent with at_least = N, agents stacked on one point or on the target, a target on the area's
corner. Each scenario is accepted and its run, written to disk, holds a number wherever the
README promises one (NaN only in the columns it says may be NaN), with no numpy or matplotlib
warning on the way; or it is refused in one line naming the key."""

import json
import math
import warnings

import numpy as np
import pyarrow.parquet as pq
import pytest

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.simulation.loop import simulate
from trackjam.simulation.output import write_run

SMALL = ["steps=4", "filter.particles=200", "filter.birth_particles=50", "control.grasp.samples=50",
         "control.grasp.iterations=2", "control.time_limit_s=0.2"]
CUED = "filter.cue={existence: 1, position_std: 1e-9, velocity_std: 1e-9}"
ALL_DOWN = ("comms.failures=[{agent: 0, step: 1, mode: breakdown}, {agent: 1, step: 1, mode: breakdown}, "
            "{agent: 2, step: 1, mode: breakdown}]")
# the README's tables: NaN where the target is absent, no report is made or no plan has a value
MAY_BE_NAN = {
    "steps": {"truth_x", "truth_y", "truth_z", "est_x", "est_y", "est_z", "aim_x", "aim_y", "aim_z", "objective", "gap"},
    "agents": set(),
    "measurements": set(),
    "targets": {"truth_x", "truth_y", "truth_z"},
    "tracks": set(),
}

CASES = [
    ("paper-fig3", ["antenna.height=1e5", "antenna.r0=1e-6"]),
    ("paper-fig3", ["area.low=[-1e5, -1e5, -1e5]", "area.high=[1e5, 1e5, 1e5]", "antenna.r0=1e-6",
                    "antenna.path_loss_exponent=10"]),
    ("paper-fig3", ["antenna.height=1e-6", "antenna.path_loss_exponent=1e-9"]),
    ("pursuit", ["steps=8", "sensor.noise_std=[1e-3, 1e-6, 1e-6]", "sensor.clutter_rate=0", "antenna.p_d_max=1", CUED,
                 "filter.accel_var=0"]),
    ("paper-fig3", ["steps=8", "fusion.share=scans", "sensor.noise_std=[1e-3, 1e-6, 1e-6]", CUED, "filter.accel_var=0"]),
    ("paper-fig3", ["sensor.noise_std=[1e4, 3.141592653589793, 3.141592653589793]", "sensor.clutter_rate=1000"]),
    ("paper-fig3", ["antenna.p_d_max=0", "control.fallback=search", "control.plan_over=belief"]),
    ("paper-fig3", ["filter.survival_prob=1", "filter.birth_prob=1", "fusion.existence=evidence", "antenna.p_d_max=1"]),
    ("paper-fig3", ["filter.survival_prob=0", "filter.birth_prob=0", "fusion.existence=evidence", CUED]),
    ("paper-fig3", ["target.accel_var=0", "filter.accel_var=0", "target.stochastic={birth_prob: 1, survival_prob: 0}"]),
    ("paper-fig3", ["antenna.power_levels_db=[off, -200]", "antenna.interference_limit_db=-200"]),
    ("paper-fig3", ["antenna.power_levels_db=[off, 60]", "antenna.interference_limit_db=60", "control.solver=exact"]),
    ("paper-fig3", ["agents.initial=[[30, 30, 30]]", "control.at_least=1", "steps=1"]),
    ("paper-fig3", ["agents.initial=[[20, 20, 20], [20, 20, 20], [20, 20, 20]]", "target.initial=[20, 20, 20, 0, 0, 0]",
                    "target.accel_var=0", "control.at_least=3"]),
    ("paper-fig3", ["target.initial=[100, 100, 100, 1000, 1000, 1000]", "agents.initial=[[100, 100, 100]]",
                    "control.at_least=1", "target.walls=leave"]),
    ("paper-fig3", ["area.high=[1, 1, 1]", "target.initial=[0, 0, 0, 0, 0, 0]",
                    "agents.initial=[[0.1, 0.1, 0.1], [0.9, 0.9, 0.9]]", "agents.radial_steps=[1e4]"]),
    ("paper-fig3", ["metrics.ospa_order=10", "metrics.ospa_cutoff=1e-9", "metrics.gate=1e-9", "fusion.report_spread=1e-9"]),
    ("paper-fig3", ["filter.visibility={hide: 1, reappear: 0}", "target.occlusions=[[1, 4]]", CUED]),
    ("paper-fig3", ["control.lead=10", "control.horizon=100", "target.initial=[20, 20, 20, 1000, -1000, 1000]"]),
    ("paper-fig3", [ALL_DOWN]),
    # the mode's grid at radii the schema allows: 1e7 cells a side overflowed its int64 count
    ("pursuit", ["filter.mode={radius: 1e-5, mass: 0.2}", "target.occlusions=[]"]),
    ("pursuit", ["filter.mode.radius=1e-300", "target.occlusions=[[2, 3]]"]),
    ("swarm-3", ["steps=3", "sensor.noise_std=[1e-3, 1e-6, 1e-6]", "antenna.p_d_max=1", "sensor.clutter_rate=0"]),
    ("swarm-3", ["steps=3", "agents.initial=[[20, 20, 20], [20, 20, 20]]", "control.at_least=2",
                 "targets=[{initial: [20, 20, 20, 0, 0, 0], accel_var: 0}, {initial: [20, 20, 20, 0, 0, 0], accel_var: 0}]"]),
    ("swarm-3", ["steps=3", "antenna.p_d_max=0", "control.fallback=search", "filter.survival_prob=1"]),
]


def _ids(case):
    preset, overrides = case
    return preset + ":" + ",".join(o.split("=")[0] for o in overrides)


def _tables(out):
    return {p.stem: pq.read_table(p).to_pydict() for p in out.glob("*.parquet")}


@pytest.mark.parametrize("case", CASES, ids=[_ids(c) for c in CASES])
def test_a_run_at_the_bounds_writes_numbers_where_numbers_are_promised(tmp_path, case):
    preset, overrides = case
    s = load_scenario(preset, SMALL + overrides)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = simulate(s)
        write_run(result, tmp_path / "run", figures=case == CASES[0] or case == CASES[-1] or case == CASES[-4])
    shown = [f"{w.category.__name__}: {w.message}" for w in caught if issubclass(w.category, (RuntimeWarning, UserWarning))]
    assert not shown
    all_down = ALL_DOWN in overrides  # the README: nobody holds a belief, so no existence
    for table, columns in _tables(tmp_path / "run").items():
        for name, values in columns.items():
            a = np.asarray(values)
            if a.dtype.kind != "f" or name in MAY_BE_NAN[table] or (all_down and name == "existence"):
                continue
            assert np.all(np.isfinite(a)), f"{table}.{name}"
    summary = json.loads((tmp_path / "run" / "summary.json").read_text(), parse_constant=lambda c: math.nan)

    def finite(key, v):
        if isinstance(v, float):
            assert math.isfinite(v), key
        for k, x in (enumerate(v) if isinstance(v, list) else v.items() if isinstance(v, dict) else ()):
            finite(f"{key}.{k}", x)

    finite("summary", summary)


def test_every_agent_down_leaves_existence_nan_and_everything_else_finite():
    r = simulate(load_scenario("paper-fig3", SMALL + [ALL_DOWN]))
    assert np.all(np.isnan(r.steps["existence"])) and np.all(np.isnan(r.agents["existence"]))
    assert set(r.agents["mode"]) == {"down"} and np.all(r.agents["power_w"] == 0)
    assert r.summary["confirmed_steps"] == 0


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["antenna.power_levels_db=[off]"], "antenna.power_levels_db"),
        (["antenna.power_levels_db=[60]"], "antenna.power_levels_db"),
        (["antenna.opening_angle_deg=170.001"], "antenna.opening_angle_deg"),
        (["sensor.noise_std=[0, 0.06, 0.06]"], "sensor.noise_std"),
        (["sensor.noise_std=[0.8, 1e-300, 0.06]"], "sensor.noise_std"),
        (["antenna.r0=0"], "antenna.r0"),
        (["antenna.height=1e5000"], "antenna.height"),
        (["control.at_least=4"], "control.at_least"),
        (["sensor.clutter_rate=1000.001"], "sensor.clutter_rate"),
        (["target.accel_var=10000.001"], "target.accel_var"),
        (["target.initial=[100.001, 0, 0, 0, 0, 0]"], "target.initial"),
    ],
)
def test_just_past_a_bound_is_refused_in_one_line_naming_the_key(overrides, key):
    with pytest.raises(ConfigError) as err:
        load_scenario("paper-fig3", SMALL + overrides)
    message = str(err.value)
    assert "\n" not in message and key in message


@pytest.mark.parametrize("radius", [5e-324, 1e-300, 1e-12, 1e-9, 1e-5, 1e-3, 5.0, 1e5])
@pytest.mark.parametrize("spread", [1e-3, 1.0, 100.0, 1e5])
def test_the_mode_kernel_and_its_numpy_twin_agree_at_any_radius(radius, spread):
    # the grid's cell count was an int64 product: past 2^63 it wrapped negative and passed the cap
    from trackjam.estimation.bernoulli import MODE_CELL_SHARE, mode_cluster_reference, mode_moments
    from trackjam.estimation.kernels import MODE_MAX_CELLS, kernel_mode_cluster

    rng = np.random.default_rng(7)
    X = np.c_[rng.normal(50, spread, (2000, 3)), rng.normal(0, 1, (2000, 3))]
    w = rng.exponential(size=2000)
    w /= w.sum()
    for cell in (MODE_CELL_SHARE * radius, 0.0):  # 0.5 x 5e-324 rounds to a cell of 0
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            c, m, inside = kernel_mode_cluster(X, w, radius, cell)
            c_ref, m_ref, inside_ref = mode_cluster_reference(X, w, radius, cell)
        np.testing.assert_allclose(c, c_ref, rtol=1e-9, atol=1e-9)
        assert m == pytest.approx(m_ref, rel=1e-9, abs=1e-12)
        np.testing.assert_array_equal(inside, inside_ref)
        assert np.all(np.isfinite(c)) and 0.0 <= m <= 1.0 + 1e-12
    moments = mode_moments(X, w, radius, 0.2)
    assert moments is None or all(np.all(np.isfinite(a)) for a in moments)
    assert MODE_MAX_CELLS == 1 << 21


def test_a_radius_below_the_particles_spacing_keeps_the_papers_moments():
    from trackjam.estimation.bernoulli import mode_moments

    X = np.zeros((10, 6))
    X[:, :3] = 1e5  # one point, far from the origin: 1e5 / 8e-301 was no int64 cell index
    w = np.full(10, 0.1)
    assert mode_moments(X, w, 1e-300, 0.2) is None  # nothing lies strictly within 1e-300 m of the centre
    mean, _ = mode_moments(X, w, 1e-9, 0.2)
    np.testing.assert_allclose(mean[:3], 1e5)


# a filter.mode cluster whose particles are copies of one (resampled, within a small radius of
# the densest point) has a singular covariance; covariance intersection inverted it as is, and the
# fused covariance came out with variances of -1e68 (a numpy "invalid value in sqrt" on stderr
# under fusion.report_spread), then reseeded the filters with a spread of 1e16 m^2
SINGULAR = np.array([
    [3.231e-27, 0.0, 3.231e-27, -1.513e-26, 7.889e-31, -2.761e-30],
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.231e-27, 0.0, 3.231e-27, -1.513e-26, 7.889e-31, -2.761e-30],
    [-1.513e-26, 0.0, -1.513e-26, 1.055, 0.7947, 0.1899],
    [7.889e-31, 0.0, 7.889e-31, 0.7947, 1.469, 0.1797],
    [-2.761e-30, 0.0, -2.761e-30, 0.1899, 0.1797, 0.6404],
])  # logged from such a run: the position of every particle of the cluster is one corner


@pytest.mark.parametrize("others", [0, 1, 2])
def test_covariance_intersection_of_a_singular_covariance_stays_a_covariance(others):
    from trackjam.estimation.fusion import covariance_intersection

    rng = np.random.default_rng(others)
    means = [np.array([100.0, 0.0, 100.0, 1.0, -1.0, 0.5])]
    covs = [SINGULAR]
    for _ in range(others):
        A = rng.normal(size=(6, 6))
        means.append(means[0] + rng.normal(size=6))
        covs.append(A @ A.T + np.eye(6))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mean, cov, omega = covariance_intersection(means, covs)
    assert np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))
    assert np.linalg.eigvalsh(cov).min() >= -1e-9 and np.trace(cov) < 100
    if others == 0:
        np.testing.assert_allclose(mean, means[0], atol=1e-3)


def test_covariance_intersection_of_well_conditioned_covariances_is_unchanged():
    # the floor leaves every covariance of an ordinary run alone: same bits as before
    from trackjam.estimation import fusion

    rng = np.random.default_rng(3)
    covs = [(lambda A: A @ A.T + np.eye(6))(rng.normal(size=(6, 6))) for _ in range(3)]
    assert all(fusion._conditioned(C) is C for C in covs)


def test_a_mode_cluster_of_copies_of_one_particle_runs_without_a_warning():
    s = load_scenario("paper-fig3", ["steps=10", "seed=6", "filter.particles=60", "filter.birth_particles=20",
                                     "control.solver=greedy", "filter.mode={radius: 0.5, mass: 0.5}",
                                     "fusion.report_spread=5e-324"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = simulate(s)
    assert np.all(np.isfinite(r.agents["existence"]))
