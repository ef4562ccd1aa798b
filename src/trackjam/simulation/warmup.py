"""Compile (or load from numba's cache) the kernels a scenario will use, before its timed run.

A first run compiles every ``@njit`` kernel, 6 to 12 s in silence, which would also land in the
run's "time per step". :func:`warm_up` runs the same scenario for two steps with a handful of
particles and GRASP samples: the kernels see the same argument types (the array sizes do not
matter to numba), so the real run compiles nothing and its step times are the kernels' own.
"""

from __future__ import annotations

from trackjam.config import Scenario

WARM_STEPS = 2


def warm_up_scenario(s: Scenario) -> Scenario:
    """The scenario's tiny twin: same agents, solver and options, two steps, few particles,
    and a target present and detectable from the first step so the update kernels run too."""
    target = s.target.model_copy(update={"appears": 1, "disappears": None, "occlusions": [], "stochastic": None})
    return s.model_copy(
        update={
            "steps": WARM_STEPS,
            "target": target,
            "filter": s.filter.model_copy(update={"particles": 40, "birth_particles": 20}),
            "control": s.control.model_copy(update={"grasp": s.control.grasp.model_copy(
                update={"samples": min(s.control.grasp.samples, 20), "iterations": 2})}),
        }
    )


def warm_up(s: Scenario) -> None:
    """Run :func:`warm_up_scenario` and discard it; nothing is written, nothing random is shared."""
    from trackjam.simulation.loop import simulate

    simulate(warm_up_scenario(s))
