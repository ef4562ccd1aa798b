"""The step's problem: candidates inside the area, Eq. (9) at x_bar, the pair gains of Eq. (13)."""

import numpy as np
import pytest

from trackjam.control.problem import build_problem, gain_table_reference
from trackjam.radio.antenna import cone_gain, detection_probability

from control_instances import HIGH, LOW, random_problem, small_displacements


def test_candidates_stay_in_area_and_hover_is_first(antenna):
    D = small_displacements()
    P = build_problem([[1.0, 50, 99.5], [50, 50, 50]], [40, 40, 40], D, antenna, LOW, HIGH, 1, True)
    assert P.n_cand[1] == len(D)
    assert P.n_cand[0] < len(D)
    for i in range(2):
        pos = P.cand_pos[i, : P.n_cand[i]]
        assert np.all((pos >= 0) & (pos <= 100))
        assert P.move[i, 0] == 0
        assert np.all(np.diff(P.move[i, : P.n_cand[i]]) > 0)


def test_detection_and_gains_match_the_antenna_model(antenna):
    rng = np.random.default_rng(1)
    P = random_problem(rng, antenna)
    for i in range(P.n_agents):
        for c in range(P.n_cand[i]):
            u = P.cand_pos[i, c]
            for l, w in enumerate(P.levels_w):
                assert np.isclose(P.p_d[i, c, l], detection_probability(P.aim, u, P.aim, w, antenna))
    i, j, ci, cj = 0, 2, 3, 5
    assert np.isclose(P.gain[i, j, ci, cj], cone_gain(P.cand_pos[i, ci], P.cand_pos[j, cj], P.aim, antenna))
    assert np.all(P.gain[np.arange(3), np.arange(3)] == 0)


def test_gain_kernel_matches_numpy_reference(antenna):
    rng = np.random.default_rng(2)
    for _ in range(3):
        P = random_problem(rng, antenna, spread=15.0)
        ref = gain_table_reference(P.cand_pos, P.n_cand, P.aim, antenna)
        np.testing.assert_allclose(P.gain, ref, rtol=1e-12, atol=1e-15)
        assert np.array_equal(P.gain > 0, ref > 0)


def test_agent_outside_area_is_rejected(antenna):
    with pytest.raises(ValueError):
        build_problem([[-1.0, 5, 5]], [5, 5, 5], small_displacements(), antenna, LOW, HIGH, 1, True)


def _cone_cases(rng, antenna):
    """Apexes scattered around an aim, axes toward it, points near, on and beyond the cones
    (some at an apex, some on the axis), with path-loss exponents 2 (numpy's square) and 2.7."""
    import dataclasses

    from trackjam.radio.antenna import axis_of

    for n_e in (2.0, 2.7):
        ant = dataclasses.replace(antenna, n_e=n_e)
        x = rng.uniform(20, 80, 3)
        apex = x + rng.normal(0, 15, (3, 7, 3))
        apex[0, 0] = x  # an apex at the aim: the axis is +z
        axis = np.ascontiguousarray(axis_of(apex, np.broadcast_to(x, apex.shape)))
        pts = x + rng.normal(0, 20, (40, 3))
        pts[0], pts[1] = apex[1, 2], x
        pts[2] = apex[2, 3] + ant.height * axis[2, 3]  # on the base's centre
        yield ant, pts, apex, axis, x


def test_cone_geometry_kernel_is_numpy_cone_gain_bit_for_bit(antenna):
    """kernel_cone_geometry (eta, inside) and cone_gain_at against the numpy antenna model."""
    from trackjam.control.problem import cone_gain_at, kernel_cone_geometry
    from trackjam.radio.antenna import inside_cone

    rng = np.random.default_rng(11)
    for ant, pts, apex, axis, x in _cone_cases(rng, antenna):
        eta, inside = kernel_cone_geometry(pts, apex, axis, float(ant.height), ant.tan_half)
        p = pts[:, None, None, :]
        aim = np.broadcast_to(x, apex.shape)[None]
        assert np.array_equal(eta, np.linalg.norm(p - apex[None], axis=-1))
        assert np.array_equal(inside, inside_cone(p, apex[None], aim, ant.height, ant.half_angle))
        ref = cone_gain(p, apex[None], aim, ant)
        assert 0 < np.count_nonzero(ref) < ref.size
        assert np.array_equal(cone_gain_at(pts, apex, axis, ant), ref)
        assert np.array_equal(cone_gain_at(x[None], apex, axis, ant)[0], cone_gain(x, apex, aim[0], ant))


def test_build_problem_p_d_tables_are_the_numpy_formulas_bit_for_bit(antenna):
    """p_d and p_d_samples as build_problem had them by numpy's cone_gain, exactly."""
    rng = np.random.default_rng(12)
    D = small_displacements()
    for _ in range(4):
        x = rng.uniform(5, 95, 3)
        u = np.clip(x + rng.normal(0, 10, (3, 3)), 0, 100)
        xs = x + rng.normal(0, 8, (16, 3))
        P = build_problem(u, x, D, antenna, LOW, HIGH, 2, True, xs)
        valid = P.move >= 0
        scale = P.levels_w / antenna.l_max * antenna.p_d_max
        aims = np.broadcast_to(x, P.cand_pos.shape)
        g = cone_gain(x, P.cand_pos, aims, antenna)
        assert np.array_equal(P.p_d, scale[None, None, :] * (g * valid)[:, :, None])
        g_s = cone_gain(xs[:, None, None, :], P.cand_pos[None], aims[None], antenna) * valid
        assert np.array_equal(P.p_d_samples, scale[None, None, None, :] * g_s[..., None])
        assert np.count_nonzero(P.p_d_samples) > 0
