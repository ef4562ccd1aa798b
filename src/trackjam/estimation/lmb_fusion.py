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

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from trackjam.arguments import covariance, real, vector
from trackjam.estimation.bernoulli import Estimate
from trackjam.estimation.fusion import RULES, FusedEstimate, fuse_unchecked
from trackjam.estimation.lmb import TrackEstimate

GATE = 16.27  # chi-square of 3 degrees of freedom at 0.999: same target beyond it is unlikely
# the largest gate fuse_tracks takes: a pair beyond it costs gate times the tracks (plus 1) in the
# assignment, which stays finite for any number of tracks below 1e200
GATE_MAX = 1e100


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
    predicted existence of ``tracks[agent][i]``, needed by rule ``evidence``.

    Checks its arguments first, as :func:`trackjam.estimation.fusion.fuse` does: every track
    has an existence in [0, 1], a finite mean of one length d >= 3 for all tracks, and a finite,
    symmetric, positive semi-definite (d, d) covariance; ``predicted`` (required by rule
    ``evidence``) one probability per track; ``rule`` ``mean`` or ``evidence``; ``gate`` in (0,
    1e100]. The engine, whose tracks its filters built, calls :func:`fuse_tracks_unchecked`;
    both give the same result."""
    tracks = _check_fuse_tracks(tracks, predicted, rule, gate)
    return fuse_tracks_unchecked(tracks, predicted, rule, gate)


def fuse_tracks_unchecked(tracks: Sequence[Sequence[TrackEstimate]],
                          predicted: Sequence[Sequence[float]] | None = None, rule: str = "mean",
                          gate: float = GATE) -> list[FusedTrack]:
    """:func:`fuse_tracks` without the checks of its arguments: the engine's, on the filters' tracks."""
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


def _listed(name: str, value, what: str) -> list:
    if isinstance(value, (str, bytes)) or not isinstance(value, Iterable):
        raise TypeError(f"{name}: expected {what}, got {type(value).__name__}")
    return list(value)


def _check_fuse_tracks(tracks, predicted, rule, gate) -> list[list]:
    """fuse_tracks' checks; returns ``tracks`` as a list of lists. One pass of numpy over all
    the tracks (a track's own check names it only when the pass finds something wrong)."""
    if not isinstance(rule, str) or rule not in RULES:
        raise ValueError(f"rule: must be one of {', '.join(RULES)}, got {rule!r:.40}")
    real("gate", gate, 0.0, GATE_MAX, above=True)
    tracks = [_listed(f"tracks[{a}]", mine, "a list of TrackEstimate")
              for a, mine in enumerate(_listed("tracks", tracks, "one list of TrackEstimate per agent"))]
    named = [(f"tracks[{a}][{i}]", t) for a, mine in enumerate(tracks) for i, t in enumerate(mine)]
    for name, t in named:
        if not all(hasattr(t, k) for k in ("label", "existence", "mean", "cov")):
            raise TypeError(f"{name}: expected a TrackEstimate (label, existence, mean, cov), got {type(t).__name__}")
    if named:
        _check_tracks(named)
    if rule == "evidence" and predicted is None:
        raise ValueError("predicted: rule 'evidence' needs every track's predicted existence")
    if predicted is not None:
        predicted = _listed("predicted", predicted, "one list of predicted existences per agent")
        if len(predicted) != len(tracks):
            raise ValueError(f"predicted: expected one list per agent ({len(tracks)}), got {len(predicted)}")
        for a, (mine, values) in enumerate(zip(tracks, predicted)):
            e = vector(f"predicted[{a}]", values, len(mine))
            if np.any((e < 0.0) | (e > 1.0)):
                raise ValueError(f"predicted[{a}]: must lie in [0, 1], got {e.tolist()!r:.60}")
    return tracks


def _check_tracks(named: list) -> None:
    e = np.array([t.existence if type(t.existence) in (float, np.float64) else np.nan for _, t in named])
    if not np.all((e >= 0.0) & (e <= 1.0)):  # the filters' are floats; anything else is checked one by one
        for name, t in named:
            real(f"{name}.existence", t.existence, 0.0, 1.0)
    try:
        means = np.array([np.asarray(t.mean) for _, t in named])
        covs = np.array([np.asarray(t.cov) for _, t in named])
        d = means.shape[1] if means.ndim == 2 else 0
        ok = (d >= 3 and covs.shape == (len(named), d, d) and means.dtype.kind in "iuf" and covs.dtype.kind in "iuf"
              and np.isfinite(means).all() and np.isfinite(covs).all())
    except (TypeError, ValueError):  # ragged
        ok = False
    if ok:
        scale = np.abs(covs).max(axis=(1, 2))
        sym = np.swapaxes(covs, 1, 2)
        ok = bool(np.all(np.abs(covs - sym) <= (1e-6 * scale)[:, None, None] + 1e-6 * np.abs(sym)))
        ok = ok and bool(np.all(np.linalg.eigvalsh(covs)[:, 0] >= -1e-9 * np.maximum(scale, 1e-300)))
    if not ok:  # the one at fault, named
        d = None
        for name, t in named:
            mean = vector(f"{name}.mean", t.mean, d)
            if d is None:
                d = len(mean)
                if d < 3:
                    raise ValueError(f"{name}.mean: expected at least 3 entries (a position first), got {d}")
            covariance(f"{name}.cov", t.cov, d)
