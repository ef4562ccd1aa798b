"""No target believed: agents hover and transmit as high as Eq. (13) allows (ours)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.fallback import fallback_levels, fallback_levels_reference, hover_gains


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.booleans())
def test_fallback_equals_brute_force(antenna, seed, n_agents, constraints):
    rng = np.random.default_rng(seed)
    x = rng.uniform(20, 80, 3)
    u = x + rng.normal(0, 10, (n_agents, 3))
    aims = x + rng.normal(0, 5, (n_agents, 3))
    lv = fallback_levels(u, aims, antenna, constraints)
    assert np.array_equal(lv, fallback_levels_reference(u, aims, antenna, constraints))
    if constraints:
        G = hover_gains(u, aims, antenna)
        assert np.all(G @ antenna.levels_w[lv] < antenna.delta_w)
    else:
        assert np.all(lv == len(antenna.levels_w) - 1)


def test_the_agent_that_jams_another_backs_off(antenna):
    u = np.array([[50.0, 50, 50], [50, 50, 60]])
    aims = np.array([[50.0, 50, 80], [50, 50, 80]])  # agent 1 sits in agent 0's cone, not vice versa
    lv = fallback_levels(u, aims, antenna, True)
    assert list(lv) == [1, 3]  # agent 0 drops to -50 dB (1e-5 W * g < delta); agent 1 keeps l_max


def test_agents_facing_each_other_both_back_off(antenna):
    u = np.array([[50.0, 50, 50], [50, 50, 60]])
    aims = np.array([[50.0, 50, 80], [50, 50, 20]])
    assert list(fallback_levels(u, aims, antenna, True)) == [1, 1]


def test_ties_between_permutations_go_to_the_lexicographically_largest(antenna):
    """Three agents on an equilateral triangle (side a = 20 m, in the plane), each aimed at the
    centroid: each sits 30 deg off the others' axes, inside their 40 deg half-angle cones, at
    gain g = (R_0 / a)^n_e from both. With delta = 1.2 g an agent stands l_max + 1e-5 W from
    the other two but not l_max + 0.2 W, so the best total is one agent at l_max and two at the
    lowest level on: three permutations with bit-equal totals. The rule (module docstring) takes
    the lexicographically largest, l_max for agent 0. Guards the branch and bound's cut
    `bound <= best`: with `<` it goes on to the equal totals after the first and keeps the last."""
    from dataclasses import replace

    a = 20.0
    centre = np.array([50.0, 50.0, 50.0])
    ang = np.deg2rad([90.0, 210.0, 330.0])
    u = centre + a / np.sqrt(3) * np.c_[np.cos(ang), np.sin(ang), np.zeros(3)]
    g = (antenna.r0 / a) ** antenna.n_e
    ant = replace(antenna, delta_w=1.2 * g)
    G = hover_gains(u, np.tile(centre, (3, 1)), ant)
    off_diagonal = G[~np.eye(3, dtype=bool)]
    np.testing.assert_allclose(off_diagonal, g, rtol=1e-12)
    top, low = len(ant.levels_w) - 1, 1
    lw = ant.levels_w
    assert (lw[top] + lw[low]) * g < ant.delta_w <= (lw[top] + lw[2]) * g  # the ties the docstring says
    for perm in ([top, low, low], [low, top, low], [low, low, top]):
        assert np.all(G @ lw[perm] < ant.delta_w)  # each permutation is allowed
    lv = fallback_levels(u, np.tile(centre, (3, 1)), ant, True)
    assert np.array_equal(lv, fallback_levels_reference(u, np.tile(centre, (3, 1)), ant, True))
    assert lv.tolist() == [top, low, low]
