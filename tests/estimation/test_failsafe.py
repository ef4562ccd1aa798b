"""filter.response (ours): the fail-safe the filters expect of a jammed target. The particle move
against the truth's own fail-safe, the jammed share against a loop over Eq. (10), the count of
jammed steps, both filters and both engines."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from trackjam.config import load_scenario
from trackjam.estimation.failsafe import FailSafe, JamWatch, fail_safe_move, following, jammed_share, move_downed, received_at
from trackjam.estimation.kernels import kernel_cv_predict
from trackjam.estimation.lmb import LMBFilter, Track
from trackjam.radio.antenna import received_power
from trackjam.simulation.build import antenna_model, fail_safe, lmb_params, make_filter
from trackjam.simulation.engine import Simulation
from trackjam.world.target import Response, TargetParams, TruthTarget

LOW, HIGH = np.zeros(3), np.full(3, 100.0)
HOME = np.array([5.0, 7.0, 0.0])

coord = st.floats(0.0, 100.0)
speed = st.floats(-9.0, 9.0)


def fs_of(action: str, speed: float = 2.0, steps: int = 3, hedge: float = 0.0) -> FailSafe:
    return FailSafe(threshold_w=1e-4, steps=steps, action=action, speed=speed, home=HOME, ground=0.0, hedge=hedge)


def truth_fail_safe(x: np.ndarray, action: str, speed: float) -> np.ndarray:
    """The truth target's own fail-safe move from state ``x``."""
    p = TargetParams(low=LOW, high=HIGH, initial=x, draw_speed=3.0, appears=1, disappears=None, occlusions=(),
                     accel_var=0.5, stochastic=None,
                     response=Response(threshold_w=1e-4, steps=3, action=action, speed=speed, home=HOME), walls="reflect")
    tgt = TruthTarget(p, np.random.default_rng(0))
    tgt.state = np.array(x, dtype=float)
    return tgt._fail_safe()


@given(st.lists(st.tuples(coord, coord, coord, speed, speed, speed), min_size=1, max_size=8),
       st.sampled_from(["land", "hover", "return"]), st.floats(0.5, 8.0))
def test_without_noise_every_particle_moves_as_the_truth_fail_safe_moves(states, action, v):
    X = np.array(states, dtype=float)
    want = np.array([truth_fail_safe(x, action, v) for x in X])
    fail_safe_move(X, np.zeros((len(X), 3)), fs_of(action, v), accel_var=0.5)
    np.testing.assert_allclose(X, want, atol=1e-12)


def test_a_landing_particle_descends_at_its_speed_then_stays_on_the_ground():
    X = np.array([[40.0, 50.0, 5.0, 3.0, -1.0, 2.0]])
    heights = []
    for _ in range(4):
        fail_safe_move(X, np.zeros((1, 3)), fs_of("land"), accel_var=0.5)
        heights.append(X[0, 2])
    assert heights == pytest.approx([3.0, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(X[0, :2], [40.0, 50.0])
    np.testing.assert_allclose(X[0, 3:], 0.0)


def test_the_position_noise_is_eq1s_and_never_goes_underground():
    rng = np.random.default_rng(5)
    X = np.tile([50.0, 50.0, 30.0, 0.0, 0.0, 0.0], (20000, 1))
    fail_safe_move(X, rng.standard_normal((len(X), 3)), fs_of("hover"), accel_var=0.5)
    # Gamma's position part is dT^2 / 2 = 1/2: std sqrt(0.5) / 2 per axis
    np.testing.assert_allclose(X[:, :3].std(axis=0), np.sqrt(0.5) / 2, rtol=0.03)
    np.testing.assert_allclose(X[:, 3:], 0.0)
    G = np.tile([50.0, 50.0, 0.1, 0.0, 0.0, -2.0], (2000, 1))
    fail_safe_move(G, rng.standard_normal((len(G), 3)), fs_of("land"), accel_var=0.5)
    assert G[:, 2].min() >= 0.0


def test_the_jammed_share_is_the_weight_that_receives_the_threshold():
    s = load_scenario("paper-fig3")
    ant = antenna_model(s)
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(0, 60, (400, 3)), np.zeros((400, 3))])
    w = rng.uniform(size=400)
    w /= w.sum()
    u = np.array([[30.0, 30.0, 30.0], [20.0, 10.0, 10.0]])
    aims = np.array([[35.0, 35.0, 40.0], [25.0, 20.0, 15.0]])
    lv = ant.levels_w[[3, 2]]
    loop = np.array([sum(float(received_power(x[:3], u[j], aims[j], lv[j], ant)) for j in range(2)) for x in X])
    np.testing.assert_allclose(received_at(X, u, aims, lv, ant), loop, rtol=1e-12)
    for thr in (1e-6, 1e-4, 1e-2):  # the compiled share against the plain-numpy powers
        assert jammed_share(X, w, u, aims, lv, ant, thr) == pytest.approx(w[loop >= thr].sum(), rel=1e-12)
        assert jammed_share(X, w, u, aims, lv, ant, thr) == pytest.approx(
            w[received_at(X, u, aims, lv, ant) >= thr].sum(), rel=1e-12)
    assert 0.0 < jammed_share(X, w, u, aims, lv, ant, 1e-4) < 1.0  # the case is not trivial
    assert jammed_share(X, w, u, aims, np.zeros(2), ant, 1e-4) == 0.0  # antennas off


def test_the_watch_downs_a_track_after_its_steps_in_a_row_and_forgets_an_unconfirmed_one():
    w = JamWatch()
    for jammed, confirmed, run, downed in [(True, True, 1, False), (True, True, 2, False), (False, True, 0, False),
                                           (True, True, 1, False), (True, True, 2, False), (True, True, 3, True),
                                           (False, True, 3, True), (True, False, 0, False)]:
        w = w.after(jammed, confirmed, 3)
        assert (w.run, w.downed) == (run, downed)
    assert JamWatch().after(True, True, 1).downed and JamWatch().after(True, True, 1).fresh


def test_a_downed_bernoulli_filter_predicts_the_fail_safe_and_a_silent_one_eq1():
    s = load_scenario("paper-fig3", ["filter.response={action: land}", "filter.birth_prob=0"])
    assert fail_safe(s) is not None and fail_safe(s).threshold_w == pytest.approx(1e-4)
    f = make_filter(s, np.random.default_rng(1))
    f.reset_to(0.99, np.array([40.0, 40.0, 30.0, 3.0, 1.0, 2.0]), np.diag([0.2, 0.2, 0.2, 0.05, 0.05, 0.05]))
    ant = antenna_model(s)
    u, aim = np.array([[40.0, 40.0, 25.0]]), np.array([[40.0, 40.0, 30.0]])  # a cone right under the track
    for k in range(3):
        assert not f.watch.downed
        f.note_jamming(u, aim, ant.levels_w[[3]])
    assert f.watch.downed
    pred = f.predict()
    np.testing.assert_allclose(pred.mean[3:], [0.0, 0.0, -2.0], atol=0.05)  # every survivor lands at 2 m/step
    assert pred.mean[2] == pytest.approx(28.0, abs=0.1)
    g = make_filter(s, np.random.default_rng(1))
    g.reset_to(0.99, np.array([40.0, 40.0, 30.0, 3.0, 1.0, 2.0]), np.diag([0.2, 0.2, 0.2, 0.05, 0.05, 0.05]))
    g.note_jamming(u, np.array([[90.0, 90.0, 90.0]]), ant.levels_w[[3]])  # the cone points away: not jammed
    assert g.watch.run == 0
    assert g.predict().mean[3] == pytest.approx(3.0, abs=0.1)


def test_only_the_lmb_track_in_the_cones_is_downed_and_lands():
    s = load_scenario("swarm-3", ["filter.response={action: land, steps: 2}"])
    p = lmb_params(s)
    f = LMBFilter(p, antenna_model(s), np.random.default_rng(4))
    rng = np.random.default_rng(0)
    tracks = []
    for i, x in enumerate(([40.0, 40.0, 30.0], [80.0, 10.0, 60.0])):
        X = np.column_stack([np.asarray(x) + 0.3 * rng.standard_normal((500, 3)), np.tile([3.0, 0.0, 1.0], (500, 1))])
        tracks.append(Track((1, i), 0.95, X, np.full(500, -np.log(500)), confirmed=True))
    f.tracks = tracks
    ant = antenna_model(s)
    for _ in range(2):
        f.note_jamming(np.array([[40.0, 40.0, 25.0]]), np.array([[40.0, 40.0, 30.0]]), ant.levels_w[[3]])
    assert [t.watch.downed for t in f.tracks] == [True, False]
    est = {e.label: e for e in f.predict()}
    np.testing.assert_allclose(est[(1, 0)].mean[3:], [0.0, 0.0, -2.0], atol=1e-9)
    assert est[(1, 1)].mean[3] == pytest.approx(3.0, abs=0.1)


def _columns(r):
    return {k: v for k, v in {**r.steps, **{f"agent_{k}": v for k, v in r.agents.items()}}.items()
            if k not in ("solve_s", "step_s")}


def test_a_response_the_team_never_triggers_changes_nothing_bit_for_bit():
    """The fail-safe draws noise only once a track is downed: a threshold no cone reaches runs
    exactly as the paper's filter (``filter.response: null``)."""
    common = ["steps=12", "filter.particles=2000", "filter.birth_particles=400", "target.response={action: land}"]
    base = Simulation(load_scenario("paper-fig3", common))
    never = Simulation(load_scenario("paper-fig3", common + ["filter.response={action: land, threshold_db: 60}"]))
    for sim in (base, never):
        while not sim.done:
            sim.step()
    a, b = _columns(base.result()), _columns(never.result())
    assert all(np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f") for k in a)


def test_the_team_downs_its_track_when_the_truth_lands_and_keeps_it():
    """Fig. 3's target lands once jammed for 3 steps (antennas pointing at the aim); with the fail-safe expected, the filters
    call it downed within a step of the truth, hold it on every step after, and track it closer
    than the paper's filter, which lags the sudden descent."""
    common = ["steps=14", "target.response={action: land}", "target.occlusions=[]", "antenna.pointing=aim"]
    held = {}
    for name, extra in (("cv", []), ("fs", ["filter.response={action: land}"])):
        sim = Simulation(load_scenario("paper-fig3", common + extra))
        downed_at = None
        while not sim.done:
            rec = sim.step()
            if downed_at is None and sim.team.agents[0].filter.watch.downed:
                downed_at = rec.t
        r = sim.result()
        truth_down = r.summary["downed_at"]
        assert truth_down is not None
        if name == "fs":
            assert downed_at is not None and abs(downed_at - truth_down) <= 1
        else:
            assert downed_at is None
        err = np.linalg.norm(np.column_stack([r.steps[f"est_{a}"] - r.steps[f"truth_{a}"] for a in "xyz"]), axis=1)
        after = r.steps["t"] > truth_down
        held[name] = (float(np.mean(np.nan_to_num(err[after], nan=np.inf) <= 5.0)), float(np.nanmean(err[after])))
    assert held["fs"][0] == 1.0 and held["fs"][1] < held["cv"][1]



def _cloud(rng, n=4000):
    return np.column_stack([rng.uniform(30, 90, (n, 3)), rng.uniform(-4, 4, (n, 3))])


@pytest.mark.parametrize("action", ["land", "hover", "return"])
def test_the_particles_that_follow_the_fail_safe_are_read_from_their_velocity(action):
    rng = np.random.default_rng(3)
    fs = fs_of(action)
    X = _cloud(rng)
    assert following(X, fs).mean() < 0.01  # flying particles do not look as if they followed it
    fail_safe_move(X, rng.standard_normal((len(X), 3)), fs, accel_var=0.5)
    assert following(X, fs).all()
    fail_safe_move(X, rng.standard_normal((len(X), 3)), fs, accel_var=0.5)  # and go on doing so
    assert following(X, fs).all()
    kernel_cv_predict(X, rng.standard_normal((len(X), 3)), 1.0, np.sqrt(0.5))
    # Eq. (1) leaves no exact zero; a step towards home stays near one for a few particles
    assert following(X, fs).mean() < (0.05 if action == "return" else 0.001)


def test_without_a_hedge_a_downed_track_moves_all_its_particles_as_before():
    X = _cloud(np.random.default_rng(1))
    Y = X.copy()
    move_downed(X, np.random.default_rng(7), fs_of("land"), 0.5, None, fresh=True)
    fail_safe_move(Y, np.random.default_rng(7).standard_normal((len(Y), 3)), fs_of("land"), 0.5)
    np.testing.assert_array_equal(X, Y)


def test_a_hedged_track_keeps_its_two_branches_from_the_downing_on():
    rng = np.random.default_rng(2)
    fs = fs_of("land", hedge=0.3)
    X = _cloud(rng, 20000)
    v0 = X[:, 3:].copy()
    cv = lambda Y: kernel_cv_predict(Y, rng.standard_normal((len(Y), 3)), 1.0, np.sqrt(0.5))  # noqa: E731
    move_downed(X, rng, fs, 0.5, cv, fresh=True)
    branch = following(X, fs)
    assert branch.mean() == pytest.approx(0.7, abs=0.02)
    # the flying branch kept its velocity up to Eq. (1)'s noise; the other one lands
    assert np.abs(X[~branch, 3:] - v0[~branch]).mean() < 1.0
    np.testing.assert_allclose(X[branch, 3:5], 0.0)
    move_downed(X, rng, fs, 0.5, cv, fresh=False)
    np.testing.assert_array_equal(following(X, fs), branch)  # nobody changes branch afterwards


def test_a_hedged_bernoulli_filter_predicts_the_mixture_of_the_two_branches():
    s = load_scenario("paper-fig3", ["filter.response={action: land, hedge: 0.25}", "filter.birth_prob=0"])
    f = make_filter(s, np.random.default_rng(1))
    f.reset_to(0.99, np.array([40.0, 40.0, 30.0, 3.0, 1.0, 2.0]), np.diag([0.2, 0.2, 0.2, 0.05, 0.05, 0.05]))
    ant = antenna_model(s)
    u, aim = np.array([[40.0, 40.0, 25.0]]), np.array([[40.0, 40.0, 30.0]])
    for _ in range(3):
        f.note_jamming(u, aim, ant.levels_w[[3]])
    assert f.watch.downed and f.watch.fresh
    pred = f.predict()
    assert not f.watch.fresh
    np.testing.assert_allclose(pred.mean[3:], 0.25 * np.array([3.0, 1.0, 2.0]) + 0.75 * np.array([0.0, 0.0, -2.0]),
                               atol=0.06)
