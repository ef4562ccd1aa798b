"""Random paper-like instances shared by the control tests."""

import numpy as np

from trackjam.control.problem import build_problem
from trackjam.world.moves import displacement_set

LOW, HIGH = (0.0, 0.0, 0.0), (100.0, 100.0, 100.0)


def small_displacements() -> np.ndarray:
    """Table I's 11 controls (one 3 m step, N_phi = 4, N_theta = 8)."""
    return displacement_set([3.0], 4, 8)


def tiny_displacements() -> np.ndarray:
    """Hover and 6 axis moves of 4 m."""
    return displacement_set([4.0], 4, 4)


def random_problem(rng, antenna, n_agents=3, at_least=2, constraints=True, displacements=None, spread=8.0):
    """A paper-like instance: agents scattered around the aim, which the antennas point at."""
    D = small_displacements() if displacements is None else displacements
    x = rng.uniform(5, 95, 3)
    u = np.clip(x + rng.normal(0, spread, (n_agents, 3)), 0, 100)
    return build_problem(u, x, D, antenna, LOW, HIGH, at_least, constraints)
