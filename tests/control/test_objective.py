"""Xi^N_n of Eq. (12) as a Poisson-binomial tail, checked against the paper's xi formula."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.control.objective import (
    at_least_probability,
    kernel_add_detector,
    kernel_at_least,
    received_interference,
)


def xi_paper(p, m):
    """Eq. (12) literally: sum over subsets {i_1 < ... < i_m} of prod_j (1 - p^j) p^{i_k}/(1 - p^{i_k})."""
    N = len(p)
    total = 0.0
    for subset in itertools.combinations(range(N), m):
        term = 1.0
        for j in range(N):
            term *= 1 - p[j]
        for i in subset:
            term *= p[i] / (1 - p[i])
        total += term
    return total


probs = st.lists(st.floats(0.0, 0.95), min_size=1, max_size=5)


@settings(max_examples=60, deadline=None)
@given(probs, st.integers(0, 6))
def test_at_least_equals_sum_of_paper_xi(p, n):
    expected = sum(xi_paper(p, m) for m in range(max(n, 0), len(p) + 1)) if n <= len(p) else 0.0
    assert np.isclose(at_least_probability(p, n), expected, rtol=1e-12, atol=1e-14)
    q = np.empty(n + 1)
    assert np.isclose(kernel_at_least(np.array(p), n, q), expected, rtol=1e-12, atol=1e-14)


def test_adding_detectors_one_by_one_gives_the_truncated_count_law():
    """q[m] = P(exactly m detect) for m < n and q[n] = P(at least n), by brute force over who detects."""
    rng = np.random.default_rng(8)
    for _ in range(40):
        N = int(rng.integers(1, 6))
        n = int(rng.integers(1, N + 1))
        p = rng.uniform(0, 1, N)
        q = np.zeros(n + 1)
        q[0] = 1.0
        for x in p:
            kernel_add_detector(q, n, x)
        exactly = np.zeros(N + 1)
        for seen in itertools.product([0, 1], repeat=N):
            exactly[sum(seen)] += np.prod([p[j] if seen[j] else 1 - p[j] for j in range(N)])
        assert np.allclose(q[:n], exactly[:n], rtol=1e-12, atol=1e-15)
        assert np.isclose(q[n], exactly[n:].sum(), rtol=1e-12, atol=1e-15)


def test_kernel_equals_numpy_bit_for_bit():
    rng = np.random.default_rng(3)
    p = rng.uniform(0, 1, (200, 6))
    for n in range(0, 8):
        ref = at_least_probability(p, n)
        q = np.empty(n + 1)
        assert all(kernel_at_least(p[k], n, q) == ref[k] for k in range(200))


def test_closed_forms():
    p = np.array([0.3, 0.6, 0.9])
    assert np.isclose(at_least_probability(p, 1), 1 - 0.7 * 0.4 * 0.1)
    assert np.isclose(at_least_probability(p, 3), 0.3 * 0.6 * 0.9)
    assert at_least_probability(p, 0) == 1.0 and at_least_probability(p, 4) == 0.0


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=2, max_size=6), st.integers(1, 6), st.integers(0, 5), st.floats(0, 1))
def test_xi_is_non_decreasing_in_each_p(p, n, j, bump):
    """The exact solver's bound rests on this."""
    p = np.array(p)
    j = j % len(p)
    hi = p.copy()
    hi[j] = p[j] + (1 - p[j]) * bump
    assert at_least_probability(hi, n) >= at_least_probability(p, n) - 1e-15


def test_interference_is_the_eq13_sum():
    rng = np.random.default_rng(0)
    N, C = 3, 4
    gain = rng.uniform(0, 1, (N, N, C, C))
    gain[np.arange(N), np.arange(N)] = 0
    levels_w = np.array([0.0, 1e-5, 0.2, 1.1])
    cand, level = np.array([1, 3, 0]), np.array([2, 0, 3])
    r = received_interference(gain, levels_w, cand, level)
    for i in range(N):
        assert np.isclose(r[i], sum(levels_w[level[j]] * gain[i, j, cand[i], cand[j]] for j in range(N) if j != i))


def _plain_feasible(gain, levels_w, delta, cand, level):
    """Eq. (13) in plain numpy, loop by loop: receiver i sums sender j's level times gain[i, j]."""
    N = len(cand)
    for i in range(N):
        r = sum(levels_w[level[j]] * gain[i, j, cand[i], cand[j]] for j in range(N) if j != i)
        if r >= delta:
            return False
    return True


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 5), st.integers(1, 4), st.integers(0, 2**32 - 1), st.floats(1e-6, 1e-1))
def test_the_compiled_eq13_check_matches_plain_numpy_and_the_vectorised_left_side(N, C, seed, delta):
    from trackjam.control.objective import kernel_feasible

    rng = np.random.default_rng(seed)
    gain = rng.exponential(1e-3, (N, N, C, C)) * (rng.random((N, N, C, C)) < 0.7)
    gain[np.arange(N), np.arange(N)] = 0.0  # as Problem.gain: no agent receives its own cone
    levels_w = np.array([0.0, 1e-5, 0.2, 1.12])
    cand = rng.integers(0, C, N)
    level = rng.integers(0, 4, N)
    expected = _plain_feasible(gain, levels_w, delta, cand, level)
    assert kernel_feasible(gain, levels_w, delta, cand, level) == expected
    assert bool(np.all(received_interference(gain, levels_w, cand, level) < delta)) == expected


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 4), st.integers(1, 3), st.integers(1, 4), st.integers(0, 2**32 - 1), st.booleans())
def test_the_exact_solvers_starting_value_is_the_belief_mean_of_xi_or_minus_inf_when_jammed(N, S, C, seed, constrained):
    from trackjam.control.exact import kernel_start_value

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, N + 1))
    p_s = rng.random((S, N, C, 4))
    w = rng.random(S)
    w /= w.sum()
    gain = rng.exponential(1e-3, (N, N, C, C))
    levels_w = np.array([0.0, 1e-5, 0.2, 1.12])
    delta = float(rng.choice([1e-6, 1e-4, 1e-2]))
    cand, level = rng.integers(0, C, N), rng.integers(0, 4, N)
    got = kernel_start_value(p_s, w, gain, levels_w, delta, n, constrained, cand, level)
    if constrained and not _plain_feasible(gain, levels_w, delta, cand, level):
        assert got == -np.inf
    else:  # the plain mean over the samples of Eq. (12) written subset by subset
        pv = p_s[:, np.arange(N), cand, level]
        brute = sum(w[s] * sum(np.prod([pv[s, i] if i in on else 1 - pv[s, i] for i in range(N)])
                               for m in range(n, N + 1) for on in itertools.combinations(range(N), m))
                    for s in range(S))
        assert got == pytest.approx(brute, abs=1e-12)


def test_received_power_of_exactly_delta_jams():
    """Eq. (13) asks for strictly less than delta: an agent receiving exactly delta is jammed.
    Powers of two make every product and sum exact, so the received power equals delta to the
    last bit (2^-7 + 2^-6 = 3 x 2^-7 here). Guards kernel_feasible's `r >= delta` (a `>` passed
    every random comparison, where exact equality never occurs)."""
    from trackjam.control.objective import kernel_feasible

    N, C = 3, 2
    gain = np.zeros((N, N, C, C))
    gain[0, 1, 1, 0] = 2.0**-3  # receiver 0 at candidate 1 hears sender 1 at candidate 0 ...
    gain[0, 2, 1, 1] = 2.0**-4  # ... and sender 2 at candidate 1
    gain[1, 0, 0, 1] = 2.0**-6  # receiver 1 hears sender 0 a little
    levels_w = np.array([0.0, 2.0**-5, 2.0**-4, 2.0**-2])
    cand, level = np.array([1, 0, 1]), np.array([3, 2, 3])
    delta = 3 * 2.0**-7
    r = received_interference(gain, levels_w, cand, level)
    assert r[0] == delta == 2.0**-3 * 2.0**-4 + 2.0**-4 * 2.0**-2  # exact, by hand
    assert r[1] < delta and r[2] < delta
    assert not _plain_feasible(gain, levels_w, delta, cand, level)
    assert not kernel_feasible(gain, levels_w, delta, cand, level)
    # one unit in the last place more tolerance, and the same plan is feasible
    above = float(np.nextafter(delta, np.inf))
    assert _plain_feasible(gain, levels_w, above, cand, level)
    assert kernel_feasible(gain, levels_w, above, cand, level)
