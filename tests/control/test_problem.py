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
