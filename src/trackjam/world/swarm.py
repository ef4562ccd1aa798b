"""Several truth targets stepped together (ours; issue 12's truth): each a :class:`TruthTarget`
with its own parameters (appearance, occlusions, jamming response) and its own random stream.

Target 0 draws from the truth's stream of the seed tree itself and target k >= 1 from that
stream's k-th child, so one target is bit for bit today's truth and adding a target never
changes the draws of those before it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from trackjam.world.target import TargetParams, TruthTarget


def target_streams(truth_seed: np.random.SeedSequence, k: int) -> list[np.random.Generator]:
    """The random streams of ``k`` targets from the truth's node of the seed tree."""
    # built from the node's key, not with spawn(), which counts earlier calls on the same node
    children = [
        np.random.SeedSequence(truth_seed.entropy, spawn_key=(*truth_seed.spawn_key, i), pool_size=truth_seed.pool_size)
        for i in range(k - 1)
    ]
    return [np.random.default_rng(s) for s in [truth_seed, *children]]


class TruthSwarm:
    """K truth targets. ``step(t)`` advances them all to step ``t`` (1-based), in list order.

    Arrays are indexed by target, in the order of ``ids``; an absent target's row is NaN."""

    def __init__(self, params: Sequence[TargetParams], ids: Sequence[int | str], rngs: Sequence[np.random.Generator]):
        if not len(params) == len(ids) == len(rngs) or not params:
            raise ValueError(f"need one id and one stream per target, got {len(params)}, {len(ids)}, {len(rngs)}")
        if len({str(i) for i in ids}) != len(ids):
            raise ValueError(f"target ids must be unique, got {list(ids)}")
        self.ids = tuple(ids)
        self.targets = [TruthTarget(p, rng) for p, rng in zip(params, rngs)]

    @classmethod
    def from_seed(cls, params: Sequence[TargetParams], ids: Sequence[int | str],
                  truth_seed: np.random.SeedSequence) -> "TruthSwarm":
        """The swarm drawing from the truth's node of the seed tree (:func:`target_streams`)."""
        return cls(params, ids, target_streams(truth_seed, len(params)))

    def __len__(self) -> int:
        return len(self.targets)

    def step(self, t: int) -> None:
        for target in self.targets:
            target.step(t)

    def apply_jamming(self, t: int, received_w: np.ndarray) -> None:
        """Each target's received power at step ``t`` [W], shape (K,): its fail-safe counts it."""
        received_w = np.asarray(received_w, dtype=float)
        if received_w.shape != (len(self),):
            raise ValueError(f"need one received power per target ({len(self)}), got shape {received_w.shape}")
        for target, w in zip(self.targets, received_w):
            target.apply_jamming(t, float(w))

    @property
    def states(self) -> np.ndarray:
        """(K, 6) true states [m, m/s]; NaN rows for absent targets."""
        out = np.full((len(self), 6), np.nan)
        for k, target in enumerate(self.targets):
            if target.state is not None:
                out[k] = target.state
        return out

    @property
    def positions(self) -> np.ndarray:
        """(K, 3) true positions [m]; NaN rows for absent targets."""
        return self.states[:, :3]

    @property
    def exists(self) -> np.ndarray:
        return np.array([t.exists for t in self.targets], dtype=bool)

    @property
    def detectable(self) -> np.ndarray:
        """(K,) present and not occluded."""
        return np.array([t.detectable for t in self.targets], dtype=bool)

    @property
    def detectable_positions(self) -> np.ndarray:
        """(K, 3) positions of the detectable targets, NaN rows for the others: what a scan can
        see and what the multi-target metrics judge against."""
        out = self.positions
        out[~self.detectable] = np.nan
        return out

    @property
    def downed_at(self) -> list[int | None]:
        """Each target's step of the fail-safe's start (None: not downed)."""
        return [t.downed_at for t in self.targets]

    def _first_states(self) -> np.ndarray:
        """(K, 6) the state each target will appear with; NaN rows for those that have appeared."""
        out = np.full((len(self), 6), np.nan)
        for k, target in enumerate(self.targets):
            first = target.first_state
            if first is not None:
                out[k] = first[:6]
        return out

    @property
    def first_velocities(self) -> np.ndarray:
        """(K, 3) the velocity each target will appear with; NaN rows for those that have appeared."""
        return self._first_states()[:, 3:6]

    @property
    def first_positions(self) -> np.ndarray:
        """(K, 3) where each target will appear; NaN rows for those that have appeared."""
        return self._first_states()[:, :3]
