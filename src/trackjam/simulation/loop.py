"""A whole run: the step-wise engine (:mod:`trackjam.simulation.engine`) stepped to the end."""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

from trackjam.simulation.engine import RunResult, Simulation

if TYPE_CHECKING:
    from trackjam.simulation.build import Scenario

__all__ = ["RunResult", "simulate"]


def simulate(scenario: Scenario, progress: Callable[[int, int], None] | None = None) -> RunResult:
    """Run one scenario end to end and return its logs and summary."""
    sim = Simulation(scenario)
    while not sim.done:
        sim.step()
        if progress is not None:
            progress(sim.t, scenario.steps)
    return sim.result()
