"""A whole run: the step-wise engine (:mod:`trackjam.simulation.engine`) stepped to the end, or
the swarm engine (:mod:`trackjam.simulation.swarm`) for a scenario with several targets."""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

from trackjam.simulation.build import several_targets
from trackjam.simulation.engine import RunResult, Simulation

if TYPE_CHECKING:
    from trackjam.simulation.build import Scenario
    from trackjam.simulation.swarm import SwarmResult

__all__ = ["RunResult", "simulate"]


def simulate(scenario: Scenario, progress: Callable[[int, int], None] | None = None) -> RunResult | SwarmResult:
    """Run one scenario end to end and return its logs and summary (a :class:`SwarmResult` for
    several targets). ``progress(t, steps)`` is called after each step."""
    if progress is not None and not callable(progress):  # else it failed after the first step's work
        raise TypeError(f"progress: expected a callable (t, steps) or None, got {type(progress).__name__}")
    if several_targets(scenario):
        from trackjam.simulation.swarm import SwarmSimulation

        sim = SwarmSimulation(scenario)
    else:
        sim = Simulation(scenario)
    while not sim.done:
        sim.step()
        if progress is not None:
            progress(sim.t, scenario.steps)
    return sim.result()
