"""OSPA(p=2, c=10) for at most one target (Section VI)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.metrics.ospa import ospa


def test_both_empty_is_zero():
    assert ospa(None, None) == 0.0


def test_exactly_one_empty_is_the_cutoff():
    x = np.array([1.0, 2.0, 3.0])
    assert ospa(x, None) == 10.0
    assert ospa(None, x) == 10.0
    assert ospa(x, None, c=4.0) == 4.0


def test_both_present_is_the_distance_cut_at_c():
    assert ospa(np.zeros(3), np.array([3.0, 4.0, 0.0])) == pytest.approx(5.0)
    assert ospa(np.zeros(3), np.array([30.0, 40.0, 0.0])) == 10.0
    # a full state's velocity is ignored: OSPA is on positions
    assert ospa(np.zeros(6), np.array([0.0, 0, 1, 9, 9, 9])) == pytest.approx(1.0)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-100, 100), min_size=6, max_size=6), st.floats(0.5, 50))
def test_ospa_is_a_bounded_symmetric_distance(v, c):
    a, b = np.array(v[:3]), np.array(v[3:])
    d = ospa(a, b, c=c)
    assert 0.0 <= d <= c
    assert d == ospa(b, a, c=c)
    assert ospa(a, a, c=c) == 0.0


def test_invalid_parameters_are_refused():
    with pytest.raises(ValueError):
        ospa(None, None, c=0.0)
