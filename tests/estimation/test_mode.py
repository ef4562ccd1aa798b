"""filter.mode (ours): the point estimate at the densest cluster of the particles. The compiled
kernel agrees with its plain-numpy twin; on clouds whose answer is known it finds it; the
filter reports it only when the cluster holds enough of the weight."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.estimation.bernoulli import (
    BernoulliFilter,
    mode_cluster_reference,
    mode_moments,
    weighted_moments,
)
from trackjam.estimation.kernels import MODE_MAX_CELLS, kernel_mode_cluster
from trackjam.simulation.build import antenna_model, build_swarm, filter_params


def cloud(rng, parts, n=4000):
    """n particles (n, 6) from isotropic Gaussian parts (share, centre (3,), std), velocities N(0, 1)."""
    counts = rng.multinomial(n, [p[0] for p in parts])
    X = np.vstack([np.c_[c + s * rng.standard_normal((k, 3)), rng.standard_normal((k, 3))]
                   for k, (_, c, s) in zip(counts, parts)])
    return X, np.full(len(X), 1.0 / len(X))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), spread=st.floats(0.5, 300.0), radius=st.floats(0.5, 20.0),
       weighted=st.booleans())
def test_kernel_matches_numpy(seed, spread, radius, weighted):
    rng = np.random.default_rng(seed)
    X = np.c_[rng.normal(50, spread, (500, 3)), rng.normal(0, 2, (500, 3))]
    w = rng.exponential(size=500) if weighted else np.ones(500)
    w /= w.sum()
    c, m, inside = kernel_mode_cluster(X, w, radius, 0.8 * radius)
    c_ref, m_ref, inside_ref = mode_cluster_reference(X, w, radius, 0.8 * radius)
    np.testing.assert_allclose(c, c_ref, rtol=1e-9, atol=1e-9)
    assert m == pytest.approx(m_ref, rel=1e-9, abs=1e-12)
    np.testing.assert_array_equal(inside, inside_ref)


def test_a_box_too_large_for_the_grid_coarsens_it_alike():
    rng = np.random.default_rng(3)
    X = np.c_[rng.uniform(-1e5, 1e5, (300, 3)), np.zeros((300, 3))]  # 1e5 m / 0.8 m cells: far above the cap
    w = np.full(300, 1 / 300)
    assert (2e5 / 0.8) ** 3 > MODE_MAX_CELLS
    c, m, inside = kernel_mode_cluster(X, w, 1.0, 0.8)
    c_ref, m_ref, inside_ref = mode_cluster_reference(X, w, 1.0, 0.8)
    np.testing.assert_allclose(c, c_ref)
    np.testing.assert_array_equal(inside, inside_ref)
    assert m == pytest.approx(w[inside].sum())


def test_zero_weights_fall_back_to_the_heaviest_cells_plain_mean():
    X = np.zeros((4, 6))
    X[:, 0] = [0.1, 0.2, 30.0, 30.2]
    c, m, inside = kernel_mode_cluster(X, np.zeros(4), 1.0, 0.8)
    c_ref, m_ref, _ = mode_cluster_reference(X, np.zeros(4), 1.0, 0.8)
    np.testing.assert_allclose(c, c_ref)
    assert m == 0.0 and m_ref == 0.0
    assert mode_moments(X, np.zeros(4), 1.0, 0.2) is None


def test_an_empty_set_is_refused_before_the_kernel_reads_past_it():
    """kernel_mode_cluster with no particle read X[0] out of bounds (NUMBA_BOUNDSCHECK=1 caught
    it): its wrapper refuses an empty set; one particle is its own cluster."""
    with pytest.raises(ValueError, match="no particles"):
        mode_moments(np.empty((0, 6)), np.empty(0), 1.0, 0.2)
    X = np.array([[1.0, 2.0, 3.0, 0.5, 0.0, 0.0]])
    mean, cov = mode_moments(X, np.ones(1), 1.0, 0.2)
    np.testing.assert_array_equal(mean, X[0])
    assert np.all(cov == 0.0)
    c, m, inside = kernel_mode_cluster(X, np.ones(1), 1.0, 0.8)
    c_ref, m_ref, inside_ref = mode_cluster_reference(X, np.ones(1), 1.0, 0.8)
    np.testing.assert_array_equal(c, c_ref)
    assert m == m_ref == 1.0 and inside.tolist() == inside_ref.tolist() == [True]


def test_the_heavier_of_two_clusters_is_found_with_its_share_and_moments():
    rng = np.random.default_rng(0)
    A, B = np.array([20.0, 30.0, 40.0]), np.array([45.0, 30.0, 40.0])  # 25 m apart
    X, w = cloud(rng, [(0.3, B, 1.0), (0.7, A, 1.0)])
    centre, mass, inside = kernel_mode_cluster(X, w, 5.0, 4.0)
    assert np.linalg.norm(centre - A) < 0.1
    # the ball of 5 m = 5 standard deviations holds all of A's particles and none of B's
    assert mass == pytest.approx(0.7, abs=0.03) and inside.sum() == pytest.approx(0.7 * len(X), abs=0.03 * len(X))
    mean, cov = mode_moments(X, w, 5.0, 0.2)
    ref_mean, ref_cov = weighted_moments(X[inside], w[inside] / w[inside].sum())
    np.testing.assert_allclose(mean, ref_mean)
    np.testing.assert_allclose(cov, ref_cov)
    assert np.allclose(np.diag(cov)[:3], 1.0, atol=0.1)  # A's own spread, not the mixture's (~ 130 m^2 along x)
    assert weighted_moments(X, w)[1][0, 0] > 100
    assert mode_moments(X, w, 5.0, 0.8) is None  # 70 % < 80 %: the paper's mean is kept


def test_a_wide_belief_has_no_mode():
    rng = np.random.default_rng(1)
    X, w = cloud(rng, [(1.0, np.array([50.0, 50.0, 50.0]), 15.0)])
    # a 5 m ball holds about P(chi2_3 < (5/15)^2) = 0.6 % of an isotropic 15 m Gaussian
    _, mass, _ = kernel_mode_cluster(X, w, 5.0, 4.0)
    assert mass < 0.05
    assert mode_moments(X, w, 5.0, 0.2) is None


def _filter(mode):
    s = load_scenario("pursuit", ["filter.mode=null" if mode is None else f"filter.mode={{radius: {mode[0]}, mass: {mode[1]}}}"])
    return BernoulliFilter(filter_params(s), antenna_model(s), np.random.default_rng(5), existence=0.9)


def test_the_filter_reports_the_mode_only_after_an_update_and_only_when_asked():
    plain, moded = _filter(None), _filter((5.0, 0.2))
    for f in (plain, moded):  # the same bimodal density in both: 70 % near A, 30 % near B, at rest
        rng = np.random.default_rng(2)
        X, w = cloud(rng, [(0.7, np.array([20.0, 30.0, 40.0]), 1.0), (0.3, np.array([45.0, 30.0, 40.0]), 1.0)],
                     n=f.n)
        X[:, 3:] = 0.0
        f._X, f._log_w, f._young = X, np.log(w), None
    pred_plain, pred_moded = plain.predict(), moded.predict()
    np.testing.assert_allclose(pred_plain.mean, pred_moded.mean)  # the predicted estimate is the paper's
    far = np.array([90.0, 90.0, 90.0])  # a scan from far away, aimed away, empty: nearly no evidence
    est_plain = plain.update(np.zeros((0, 3)), far, far + 1.0, 1.0)
    est_moded = moded.update(np.zeros((0, 3)), far, far + 1.0, 1.0)
    assert est_plain.mean[0] == pytest.approx(27.5, abs=1.0)  # between the clusters
    assert est_moded.mean[0] == pytest.approx(20.0, abs=0.5)  # at the heavier one
    assert np.trace(est_moded.cov[:3, :3]) < np.trace(est_plain.cov[:3, :3]) / 10
    assert est_moded.existence == pytest.approx(est_plain.existence, abs=0.02)


def test_the_preset_pursuit_reports_at_the_mode():
    assert filter_params(load_scenario("pursuit")).mode == (5.0, 0.2)
    assert filter_params(load_scenario("paper-fig3")).mode is None


def test_bad_mode_parameters_are_refused_by_the_filter():
    s = load_scenario("pursuit")
    from dataclasses import replace
    with pytest.raises(ValueError, match="mode"):
        BernoulliFilter(replace(filter_params(s), mode=(0.0, 0.2)), antenna_model(s), np.random.default_rng(0))


def test_the_swarm_engine_refuses_the_mode_in_one_line():
    with pytest.raises(ConfigError, match=r"filter.mode: \{.radius.: 5.0, .mass.: 0.2\} is not simulated") as info:
        build_swarm(load_scenario("swarm-3", ["filter.mode={radius: 5, mass: 0.2}"]))
    assert "\n" not in str(info.value)


def test_masked_moments_are_the_subsets_weighted_moments():
    from trackjam.estimation.kernels import kernel_masked_moments
    rng = np.random.default_rng(4)
    X, w = rng.normal(size=(300, 6)), rng.exponential(size=300)
    inside = rng.uniform(size=300) < 0.3
    mean, cov = kernel_masked_moments(X, w, inside, w[inside].sum())
    ref = np.cov(X[inside].T, aweights=w[inside], bias=True)
    np.testing.assert_allclose(mean, np.average(X[inside], axis=0, weights=w[inside]))
    np.testing.assert_allclose(cov, ref, atol=1e-12)
