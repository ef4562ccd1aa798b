"""Fusion of the agents' labelled tracks (ours: several targets; end of Section V-A per track).

Track-to-track association, agent by agent: the clusters found so far are matched to the next
agent's tracks by one linear assignment (Hungarian) on the squared Mahalanobis distance of the
positions, d^2 = (m_a - m_b)^T (C_a + C_b)^{-1} (m_a - m_b), C the 3x3 position blocks; a cluster
is represented by its most likely member. The assignment first makes as many pairs within the
gate as it can, then the cheapest; pairs beyond the gate stay apart. A cluster holds at most one
track of each agent, and a track matched to none starts a cluster of its own, so nothing an
agent reports is dropped.

Each cluster is fused by :func:`trackjam.estimation.fusion.fuse` over its members: the
existence by the rule (``mean``: the mean over the agents that hold the track; ``evidence``:
their likelihood ratios on the mean predicted existence), the state by covariance intersection
of the members with e > 0.5. An agent without a track in the cluster does not vote: its cone
may serve another target. With one track per agent, all within the gate, this is ``fuse``
itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from trackjam.estimation.bernoulli import Estimate
from trackjam.estimation.fusion import FusedEstimate, fuse_unchecked
from trackjam.estimation.lmb import TrackEstimate

GATE = 16.27  # chi-square of 3 degrees of freedom at 0.999: same target beyond it is unlikely


@dataclass(frozen=True)
class FusedTrack:
    """One target as the team sees it: the (agent, label) of each member track and the fused
    estimate (``FusedEstimate.weights`` follows ``members``)."""

    members: tuple[tuple[int, tuple[int, int]], ...]
    estimate: FusedEstimate


def _positions(ts: Sequence[TrackEstimate]) -> np.ndarray:
    return np.array([np.asarray(t.mean, float)[:3] for t in ts]).reshape(-1, 3)


def _position_covs(ts: Sequence[TrackEstimate]) -> np.ndarray:
    return np.array([np.asarray(t.cov, float)[:3, :3] for t in ts]).reshape(-1, 3, 3)


def mahalanobis2_matrix(A: Sequence[TrackEstimate], B: Sequence[TrackEstimate]) -> np.ndarray:
    """d^2 (len(A), len(B)) of every pair of tracks' positions under the sum of their position
    covariances (the pseudo-inverse: a track whose particles collapsed to one point has none)."""
    d = _positions(A)[:, None, :] - _positions(B)[None, :, :]
    S = _position_covs(A)[:, None] + _position_covs(B)[None, :]
    P = np.linalg.pinv(0.5 * (S + np.swapaxes(S, -1, -2)), hermitian=True)
    return (d[..., None, :] @ P @ d[..., :, None])[..., 0, 0]


def mahalanobis2(a: TrackEstimate, b: TrackEstimate) -> float:
    """d^2 of two tracks' positions under the sum of their position covariances."""
    return float(mahalanobis2_matrix([a], [b])[0, 0])


def associate_tracks(tracks: Sequence[Sequence[TrackEstimate]], gate: float = GATE) -> list[list[tuple[int, int]]]:
    """Clusters of ``(agent, index)`` over the agents' track lists (the module docstring)."""
    clusters: list[list[tuple[int, int]]] = []
    for agent, mine in enumerate(tracks):
        if not mine:
            continue
        if clusters:
            reps = [max(c, key=lambda ai: tracks[ai[0]][ai[1]].existence) for c in clusters]
            D = mahalanobis2_matrix([tracks[a][i] for a, i in reps], mine)
            # a pair beyond the gate costs more than all pairs within it together, so the
            # assignment makes as few of them as it can
            outside = gate * (min(D.shape) + 1) + 1.0
            rows, cols = linear_sum_assignment(np.where(D <= gate, D, outside))
            matched = {c: r for r, c in zip(rows, cols) if D[r, c] <= gate}
        else:
            matched = {}
        for j in range(len(mine)):
            if j in matched:
                clusters[matched[j]].append((agent, j))
            else:
                clusters.append([(agent, j)])
    return clusters


def fuse_tracks(tracks: Sequence[Sequence[TrackEstimate]], predicted: Sequence[Sequence[float]] | None = None,
                rule: str = "mean", gate: float = GATE) -> list[FusedTrack]:
    """The team's tracks from every agent's (``tracks[agent]``); ``predicted[agent][i]`` is the
    predicted existence of ``tracks[agent][i]``, needed by rule ``evidence``."""
    fused = []
    for cluster in associate_tracks(tracks, gate):
        members = [tracks[a][i] for a, i in cluster]
        est = fuse_unchecked(
            [Estimate(t.existence, t.mean, t.cov) for t in members],
            None if predicted is None else [predicted[a][i] for a, i in cluster],
            rule,
        )
        fused.append(FusedTrack(tuple((a, tracks[a][i].label) for a, i in cluster), est))
    return fused
