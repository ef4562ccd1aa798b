"""GRASP's unrolled objective is the general recursion, bit for bit."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from trackjam.control.grasp import _sample_xi, _xi_unrolled
from trackjam.control.objective import kernel_at_least


@njit(cache=False)
def _call(p_flat, kk, n):
    N = kk.shape[0]
    return _sample_xi(p_flat, kk, n, np.empty(N), np.empty(max(n, 0) + 1))


@settings(max_examples=300, deadline=None)
@given(
    N=st.integers(1, 6),
    n=st.integers(0, 7),
    seed=st.integers(0, 2**32 - 1),
)
def test_unrolled_xi_equals_the_recursion_exactly(N, n, seed):
    rng = np.random.default_rng(seed)
    p_flat = rng.random((N, 9))
    p_flat[rng.random((N, 9)) < 0.2] = 0.0
    kk = rng.integers(0, 9, size=N)
    p = p_flat[np.arange(N), kk]
    expected = kernel_at_least(p, n, np.empty(max(n, 0) + 1))
    assert _call(p_flat, kk, n) == expected  # identical bits, not approximately


@njit(cache=False)
def _unrolled(p_flat, kk, n):
    return _xi_unrolled(p_flat, kk, n)


@settings(max_examples=200, deadline=None)
@given(N=st.integers(1, 6), n=st.integers(1, 3), seed=st.integers(0, 2**32 - 1))
def test_the_unrolled_cases_alone_equal_the_recursion_exactly(N, n, seed):
    """_xi_unrolled, which GRASP's hot loop calls without the general fallback, for 1 <= n <= min(3, N)."""
    n = min(n, N)
    rng = np.random.default_rng(seed)
    p_flat = rng.random((N, 9))
    p_flat[rng.random((N, 9)) < 0.2] = 0.0
    kk = rng.integers(0, 9, size=N)
    p = p_flat[np.arange(N), kk]
    assert _unrolled(p_flat, kk, n) == kernel_at_least(p, n, np.empty(n + 1))
