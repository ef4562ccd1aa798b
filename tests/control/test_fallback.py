"""No target believed: agents hover and transmit as high as Eq. (13) allows (ours)."""

import numpy as np
import pytest
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


@pytest.mark.parametrize("sender_first", [True, False])
def test_an_agent_receiving_exactly_delta_is_jammed(antenna, sender_first):
    """Eq. (13) asks for strictly less than delta. Agent "in" sits in the sender's cone, not the
    reverse; delta is set to the sender's l_max times that one gain, so at l_max the receiver gets
    delta to the last bit (one product, nothing summed), and the sender must drop one level.
    Both of the search's checks are exercised: the sender placed first (the receiver's own
    check, `inc >= delta`) and the receiver first (`recv >= delta`, on an agent already placed).
    Random geometry never hits delta exactly, so `>` in either check passed the brute-force test."""
    from dataclasses import replace

    sender, receiver = np.array([50.0, 50, 50]), np.array([50.0, 50, 60])
    aim = np.array([50.0, 50, 80])  # both aimed up: the receiver is in the sender's cone
    u = np.array([sender, receiver] if sender_first else [receiver, sender])
    s, r = (0, 1) if sender_first else (1, 0)
    aims = np.tile(aim, (2, 1))
    G = hover_gains(u, aims, antenna)
    assert G[r, s] > 0 and G[s, r] == 0
    lw = antenna.levels_w
    top = len(lw) - 1
    ant = replace(antenna, delta_w=float(lw[top] * G[r, s]))
    assert (G @ lw[[top, top]])[r] == ant.delta_w  # exactly delta, by construction
    assert lw[top - 1] * G[r, s] < ant.delta_w
    want = np.full(2, top)
    want[s] = top - 1
    for got in (fallback_levels(u, aims, ant, True), fallback_levels_reference(u, aims, ant, True)):
        assert got.tolist() == want.tolist()
    # one unit in the last place more, and both keep l_max
    above = replace(antenna, delta_w=float(np.nextafter(ant.delta_w, np.inf)))
    assert fallback_levels(u, aims, above, True).tolist() == [top, top]
