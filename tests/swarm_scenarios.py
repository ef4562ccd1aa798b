"""A small two-target scenario the swarm-engine tests share."""

from __future__ import annotations

from trackjam.config import load_scenario

TWO_TARGETS = [
    "target=null",
    "targets=[{id: a, initial: [20, 20, 20, 1.5, 2.0, 1.7]}, {id: b, initial: [60, 60, 60, -1, 0, 0]}]",
    "agents.initial=[[30, 30, 30], [20, 10, 10], [60, 50, 50]]",
    "filter.particles=300", "filter.birth_particles=100",
    "filter.cue={existence: 0.9, position_std: 2, velocity_std: 2}",
    "antenna.pointing=aim", "fusion.existence=mean", "control.fallback=hover",
]


def two_targets(*extra: str):
    """Two targets, three agents, few particles, with ``extra`` overrides on top."""
    return load_scenario("paper-fig3", [*TWO_TARGETS, *extra])
