"""Compile (or load from numba's cache) the kernels a scenario will use, before its timed run.

A first run compiles every ``@njit`` kernel, 6 to 12 s in silence, which would also land in the
run's "time per step". :func:`warm_up` runs the same scenario for two steps with a handful of
particles and GRASP samples (its twin, :func:`trackjam.simulation.build.warm_up_scenario`): the
kernels see the same argument types (the array sizes do not matter to numba), so the real run
compiles nothing and its step times are the kernels' own.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from trackjam.simulation.build import Scenario


def warm_up(s: Scenario) -> None:
    """Run the scenario's warm-up twin and discard it; nothing is written, nothing random is shared."""
    from trackjam.simulation.build import warm_up_scenario
    from trackjam.simulation.loop import simulate

    simulate(warm_up_scenario(s))
