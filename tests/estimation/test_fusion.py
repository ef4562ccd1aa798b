"""Fusion at the end of Section V-A: mean existence and covariance intersection (CI) of the
agents with e > 0.5."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.estimation.bernoulli import Estimate
from trackjam.estimation.fusion import covariance_intersection, fuse


def spd(rng, d=6, scale=1.0):
    A = rng.normal(0, scale, (d, d))
    return A @ A.T + 0.1 * np.eye(d)


def textbook_ci(omega, means, covs):
    """C = (sum_j omega_j C_j^{-1})^{-1}, x = C sum_j omega_j C_j^{-1} x_j."""
    info = sum(w * np.linalg.inv(C) for w, C in zip(omega, covs))
    C = np.linalg.inv(info)
    return C @ sum(w * np.linalg.inv(Cj) @ m for w, Cj, m in zip(omega, covs, means)), C


def test_two_estimates_match_the_textbook_formula_at_the_optimal_weight():
    rng = np.random.default_rng(0)
    means = [rng.normal(0, 5, 6), rng.normal(0, 5, 6)]
    covs = [spd(rng), spd(rng, scale=2.0)]
    mean, cov, omega = covariance_intersection(means, covs)
    # the optimal weight, by brute force over a fine grid
    grid = np.linspace(0, 1, 20001)
    traces = [np.trace(textbook_ci([w, 1 - w], means, covs)[1]) for w in grid]
    assert omega[0] == pytest.approx(grid[int(np.argmin(traces))], abs=2e-4)
    assert np.trace(cov) <= min(traces) + 1e-9
    ref_mean, ref_cov = textbook_ci(omega, means, covs)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-10)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-10)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**16), k=st.integers(2, 4))
def test_ci_trace_no_larger_than_any_input_and_order_free(seed, k):
    rng = np.random.default_rng(seed)
    means = [rng.normal(0, 5, 6) for _ in range(k)]
    covs = [spd(rng, scale=rng.uniform(0.3, 3)) for _ in range(k)]
    mean, cov, omega = covariance_intersection(means, covs)
    assert np.all(omega >= 0) and omega.sum() == pytest.approx(1.0)
    assert np.trace(cov) <= min(np.trace(C) for C in covs) + 1e-8
    np.testing.assert_allclose(cov, cov.T)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    for perm in itertools.islice(itertools.permutations(range(k)), 1, 4):
        m2, c2, w2 = covariance_intersection([means[i] for i in perm], [covs[i] for i in perm])
        assert np.trace(c2) == pytest.approx(np.trace(cov), rel=1e-6)
        np.testing.assert_allclose(m2, mean, atol=1e-3 * (1 + np.abs(mean).max()))


def test_ci_of_one_estimate_is_itself_and_identical_estimates_stay_put():
    rng = np.random.default_rng(1)
    m, C = rng.normal(0, 1, 6), spd(rng)
    mean, cov, omega = covariance_intersection([m], [C])
    np.testing.assert_allclose(mean, m)
    np.testing.assert_allclose(cov, C, rtol=1e-12)
    mean, cov, _ = covariance_intersection([m, m, m], [C, C, C])
    np.testing.assert_allclose(mean, m, rtol=1e-8)
    np.testing.assert_allclose(cov, C, rtol=1e-6)


def est(e, m=None, C=None):
    return Estimate(e, np.zeros(6) if m is None else m, np.eye(6) if C is None else C)


def test_fused_existence_is_the_mean_and_only_sensing_agents_are_combined():
    rng = np.random.default_rng(2)
    a = est(0.9, rng.normal(0, 1, 6), spd(rng))
    b = est(0.2, rng.normal(0, 1, 6) + 100, spd(rng))  # far away, but e <= 0.5: ignored
    c = est(0.7, rng.normal(0, 1, 6), spd(rng))
    fused = fuse([a, b, c])
    assert fused.existence == pytest.approx(0.6)
    assert fused.weights[1] == 0.0 and fused.weights.sum() == pytest.approx(1.0)
    mean, cov, omega = covariance_intersection([a.mean, c.mean], [a.cov, c.cov])
    np.testing.assert_allclose(fused.mean, mean)
    np.testing.assert_allclose(fused.weights[[0, 2]], omega)


def test_no_sensing_agent_gives_no_state():
    fused = fuse([est(0.5), est(0.1)])
    assert fused.existence == pytest.approx(0.3)
    assert fused.mean is None and fused.cov is None
    assert np.all(fused.weights == 0)


def test_singular_covariance_does_not_break_fusion():
    C = np.zeros((6, 6))
    fused = fuse([est(0.9, np.ones(6), C), est(0.8, np.ones(6), np.eye(6))])
    assert np.all(np.isfinite(fused.mean)) and np.all(np.isfinite(fused.cov))


_CI_SCRIPT = """
import sys, numpy as np
from trackjam.estimation.fusion import covariance_intersection
rng = np.random.default_rng(7)
rows = []
for _ in range(12):
    means = rng.normal(size=(3, 6)) * 10
    covs = [(lambda A: A @ A.T + np.eye(6))(rng.normal(size=(6, 6))) for _ in range(3)]
    m, C, w = covariance_intersection(means, covs)
    rows.append(np.concatenate([m, C.ravel(), w]))
sys.stdout.write(np.array(rows).tobytes().hex())
"""


def test_covariance_intersection_gives_the_same_bits_whatever_blas_threads_the_process_has():
    # SLSQP's weights differed in the 8th digit under OMP_NUM_THREADS=1 (Dask's workers), so a
    # sweep on Dask differed from the same sweep on the local pool
    import os
    import subprocess
    import sys

    def run(threads: str | None) -> str:
        env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
        if threads is not None:
            env |= {"OMP_NUM_THREADS": threads, "OPENBLAS_NUM_THREADS": threads}
        return subprocess.run([sys.executable, "-c", _CI_SCRIPT], env=env, capture_output=True, text=True,
                              check=True, timeout=300).stdout

    single, default, four = run("1"), run(None), run("4")
    assert len(single) == 12 * (6 + 36 + 3) * 16
    assert single == default == four


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_three_estimates_reach_the_grid_optimum_of_the_trace(seed):
    """The paper fuses three agents: the SLSQP weights are checked against a grid over the 2-simplex
    (a search that stopped short would pass the trace-below-inputs test above)."""
    rng = np.random.default_rng(100 + seed)
    means = [rng.normal(0, 5, 6) for _ in range(3)]
    covs = [spd(rng, scale=s) for s in (0.5, 1.0, 2.0)]
    _, cov, omega = covariance_intersection(means, covs)
    best = np.inf
    steps = np.linspace(0, 1, 151)
    for a in steps:
        for b in steps[steps <= 1 - a + 1e-12]:
            best = min(best, np.trace(textbook_ci([a, b, max(1 - a - b, 0.0)], means, covs)[1]))
    assert np.trace(cov) <= best + 1e-9
    assert np.trace(cov) >= best - 0.01 * best  # and the grid is fine enough to come near it
