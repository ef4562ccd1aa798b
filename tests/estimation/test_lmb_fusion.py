"""Fusion of labelled tracks across agents: track-to-track association by linear assignment
within a Mahalanobis gate, then the paper's fusion per matched cluster."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from trackjam.estimation.bernoulli import Estimate
from trackjam.estimation.fusion import fuse
from trackjam.estimation.lmb import TrackEstimate
from trackjam.estimation.lmb_fusion import GATE, associate_tracks, fuse_tracks, mahalanobis2, mahalanobis2_matrix


def track(label, e, pos, std=1.0, vel=(0.0, 0.0, 0.0)):
    return TrackEstimate(label, e, np.array([*pos, *vel], float), np.diag([std**2] * 3 + [0.5] * 3))


def assert_same(fused, expected):
    assert fused.existence == pytest.approx(expected.existence, abs=1e-12)
    if expected.mean is None:
        assert fused.mean is None
    else:
        np.testing.assert_allclose(fused.mean, expected.mean, atol=1e-9)
        np.testing.assert_allclose(fused.cov, expected.cov, atol=1e-9)
    np.testing.assert_allclose(fused.weights, expected.weights, atol=1e-9)


def test_mahalanobis_of_positions():
    a, b = track((1, 0), 0.9, (0, 0, 0), std=1.0), track((1, 0), 0.9, (2, 0, 0), std=1.0, vel=(9, 9, 9))
    assert mahalanobis2(a, b) == pytest.approx(4.0 / 2.0)  # velocities do not count


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.integers(1, 5))
def test_mahalanobis_matrix_is_every_pair(seed, na, nb):
    """The batched d^2 equals the pair's own pseudo-inverse formula, a collapsed track (zero
    covariance) and a flat one included."""
    rng = np.random.default_rng(seed)

    def tracks(n):
        out = []
        for i in range(n):
            L = rng.normal(0, 2, (6, 6))
            cov = [L @ L.T, np.zeros((6, 6)), np.diag([1.0, 1.0, 0.0, 1.0, 1.0, 1.0])][rng.integers(3)]
            out.append(TrackEstimate((1, i), 0.9, rng.normal(0, 5, 6), cov))
        return out

    A, B = tracks(na), tracks(nb)
    D = mahalanobis2_matrix(A, B)
    assert D.shape == (na, nb)
    for i, a in enumerate(A):
        for j, b in enumerate(B):
            d = a.mean[:3] - b.mean[:3]
            S = a.cov[:3, :3] + b.cov[:3, :3]
            assert D[i, j] == pytest.approx(d @ np.linalg.pinv(S) @ d, rel=1e-9, abs=1e-9)
            assert mahalanobis2(a, b) == pytest.approx(D[i, j], rel=1e-12, abs=1e-12)


def test_two_agents_with_the_same_track_give_one():
    a = track((2, 0), 0.9, (40, 50, 35), std=1.0)
    b = track((5, 1), 0.8, (40.8, 49.5, 35.3), std=1.5)
    (f,) = fuse_tracks([[a], [b]])
    assert f.members == ((0, (2, 0)), (1, (5, 1)))
    assert_same(f.estimate, fuse([Estimate(a.existence, a.mean, a.cov), Estimate(b.existence, b.mean, b.cov)]))


def test_far_apart_tracks_stay_two():
    a, b = track((2, 0), 0.9, (40, 50, 35)), track((2, 0), 0.9, (60, 50, 35))
    fused = fuse_tracks([[a], [b]])
    assert [f.members for f in fused] == [((0, (2, 0)),), ((1, (2, 0)),)]
    for f, t in zip(fused, (a, b)):
        assert f.estimate.existence == 0.9
        np.testing.assert_allclose(f.estimate.mean, t.mean)


@pytest.mark.parametrize("rule", ["mean", "evidence"])
def test_one_target_equals_todays_fuse(rule):
    """K = 1: one track per agent, all within the gate (one agent unsure, its density wide): the
    one fused track is fuse() of the agents' estimates, existence rule and CI included."""
    tracks = [[track((1, 0), 0.95, (20, 20, 20), 0.8)], [track((3, 0), 0.7, (21, 19.5, 20.4), 1.2)],
              [track((1, 0), 0.2, (26, 30, 10), 15.0)]]
    predicted = [[0.9], [0.5], [0.3]]
    (f,) = fuse_tracks(tracks, predicted, rule)
    assert len(f.members) == 3
    assert_same(f.estimate, fuse([Estimate(t.existence, t.mean, t.cov) for (t,) in tracks], [0.9, 0.5, 0.3], rule))


def test_unmatched_tracks_are_kept_and_each_agent_adds_at_most_one_per_cluster():
    """Agent 1 holds two tracks near agent 0's one: one joins it, the other stays its own."""
    tracks = [[track((1, 0), 0.9, (10, 10, 10))],
              [track((1, 0), 0.9, (10.5, 10, 10)), track((1, 1), 0.6, (11, 10.5, 10)),
               track((1, 2), 0.4, (80, 80, 80))]]
    clusters = associate_tracks(tracks)
    assert sorted(map(sorted, clusters)) == [[(0, 0), (1, 0)], [(1, 1)], [(1, 2)]]
    fused = fuse_tracks(tracks)
    assert sorted(f.estimate.existence for f in fused) == pytest.approx([0.4, 0.6, 0.9])


def brute_force_pairs(A, B, gate):
    """The best matching of A's and B's tracks: most pairs within the gate, then least d^2."""
    options = []
    small, large, swap = (A, B, False) if len(A) <= len(B) else (B, A, True)
    for perm in itertools.permutations(range(len(large)), len(small)):
        pairs = [(i, j) for i, j in enumerate(perm) if mahalanobis2(small[i], large[j]) <= gate]
        cost = sum(mahalanobis2(small[i], large[j]) for i, j in pairs)
        options.append((-len(pairs), cost, sorted((j, i) if swap else (i, j) for i, j in pairs)))
    return min(options, key=lambda o: (o[0], o[1]))[:2]


position = st.tuples(*[st.floats(0, 12) for _ in range(3)])


@settings(max_examples=60, deadline=None)
@given(st.lists(position, min_size=1, max_size=4), st.lists(position, min_size=1, max_size=4))
def test_association_is_the_best_matching(pa, pb):
    """Two agents: the pairs made are a matching with the most pairs within the gate and, among
    those, the least total d^2 (brute force over every matching)."""
    A = [track((1, i), 0.9, p) for i, p in enumerate(pa)]
    B = [track((1, i), 0.9, p) for i, p in enumerate(pb)]
    clusters = associate_tracks([A, B])
    pairs = sorted((c[0][1], c[1][1]) for c in clusters if len(c) == 2)
    assert sum(len(c) for c in clusters) == len(A) + len(B)
    n_best, cost_best = brute_force_pairs(A, B, GATE)
    assert len(pairs) == -n_best
    assert sum(mahalanobis2(A[i], B[j]) for i, j in pairs) == pytest.approx(cost_best, abs=1e-9)


def test_no_tracks():
    assert fuse_tracks([[], []]) == []


@pytest.mark.parametrize("agents", [2, 3, 5])
def test_fusing_copies_of_one_track_gives_it_back(agents):
    """Every agent holds the same track (a full, correlated covariance): one cluster whose fused
    existence, mean and covariance are the track's (rule ``mean``; covariance intersection of
    equal estimates is the estimate), whatever the weights."""
    rng = np.random.default_rng(agents)
    A = rng.normal(size=(6, 6))
    t = TrackEstimate((2, 0), 0.83, rng.uniform(0, 100, 6), A @ A.T + 0.1 * np.eye(6))
    (f,) = fuse_tracks([[t] for _ in range(agents)])
    assert f.members == tuple((a, (2, 0)) for a in range(agents))
    assert f.estimate.existence == pytest.approx(t.existence, abs=1e-15)
    np.testing.assert_allclose(f.estimate.mean, t.mean, rtol=0, atol=1e-9)
    np.testing.assert_allclose(f.estimate.cov, t.cov, rtol=1e-12, atol=1e-12)
    assert f.estimate.weights.sum() == pytest.approx(1.0)
