"""Where a pursuing team aims (ours, beyond the paper): ahead of x_bar rather than at it.

Eq. (12) plans at x_bar, the mean predicted position at t. A target faster than the agents'
largest step then stays ahead of a team that always plans at where it is now. Two options move
the aim along the believers' mean predicted velocity v_bar:

- ``control.lead`` = lambda [steps]: aim at x_bar + lambda v_bar;
- ``control.horizon`` = H [steps] (intercept): aim at the target's coasted position x_bar +
  (k - 1) v_bar at the first k in 1..H at which the agent nearest to it can be there,
  ``|u - (x_bar + (k - 1) v_bar)| <= k R`` with R the largest radial step; k = H when none can.
  A target within one step's reach gives k = 1, x_bar itself; a short receding horizon over the
  control set, replanned every step.

Both together aim at x_bar + (k - 1 + lambda) v_bar. lambda = 0 and H = 1 is the paper's x_bar,
bit for bit. A searching team (``control.fallback: search``) moves its search point, the lost
track coasted by Eq. (1), ahead along the coasted velocity the same way.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from trackjam.control.planning import planning_aim, search_point
from trackjam.estimation.fusion import CONFIRM


@dataclass(frozen=True)
class AimSettings:
    """The options that move the planning aim ahead of x_bar."""

    lead: float = 0.0  # lambda, control.lead [steps]
    horizon: int = 1  # H, control.horizon [steps]
    reach: float = 5.0  # R, the largest radial step of Eq. (3) [m]

    @property
    def paper(self) -> bool:
        return self.lead == 0.0 and self.horizon == 1


def believers_state(predicted: Sequence) -> tuple[np.ndarray, np.ndarray] | None:
    """(x_bar, v_bar): the mean predicted position and velocity of the agents whose predicted
    existence exceeds 0.5; None when no agent believes in the target."""
    states = [est.mean for est in predicted if est.existence > CONFIRM]
    if not states:
        return None
    mean = np.mean(states, axis=0)
    return mean[:3], mean[3:6]


def intercept_steps(x_bar: np.ndarray, v_bar: np.ndarray, positions: np.ndarray, reach: float,
                    horizon: int) -> int:
    """The first k in 1..``horizon`` at which the agent nearest to the coasted target position
    x_bar + (k - 1) v_bar can reach it in k steps of at most ``reach`` metres; ``horizon``
    when none can."""
    u = np.atleast_2d(np.asarray(positions, dtype=float))
    for k in range(1, horizon + 1):
        p = x_bar + (k - 1) * v_bar
        if np.min(np.linalg.norm(u - p, axis=1)) <= k * reach:
            return k
    return horizon


def aim_ahead(x_bar: np.ndarray, v_bar: np.ndarray, positions: np.ndarray, settings: AimSettings) -> np.ndarray:
    """x_bar + (k - 1 + lambda) v_bar (module docstring); x_bar itself under the paper's settings."""
    if settings.paper:
        return x_bar
    k = intercept_steps(x_bar, v_bar, positions, settings.reach, settings.horizon)
    return x_bar + (k - 1 + settings.lead) * v_bar


def pursuit_aim(predicted: Sequence, positions: np.ndarray, settings: AimSettings,
                low: np.ndarray, high: np.ndarray) -> np.ndarray | None:
    """The planning aim from the predictions an agent received: x_bar of Eq. (12) moved ahead by
    :func:`aim_ahead` and kept inside the area; None when no agent believes in the target."""
    if settings.paper:
        return planning_aim(predicted)
    state = believers_state(predicted)
    if state is None:
        return None
    x_bar, v_bar = state
    return np.clip(aim_ahead(x_bar, v_bar, positions, settings), low, high)


def search_aim(coasted: Sequence[np.ndarray], predicted: Sequence, aims: np.ndarray, positions: np.ndarray,
               settings: AimSettings, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """:func:`~trackjam.control.planning.search_point`, moved ahead along the mean coasted velocity
    by :func:`aim_ahead` when the team searches for a lost track and the options ask for it."""
    point = search_point(coasted, predicted, aims, low, high)
    if settings.paper or not len(coasted):
        return point
    v = np.mean([c[3:6] for c in coasted], axis=0)
    return np.clip(aim_ahead(point, v, positions, settings), low, high)

