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
