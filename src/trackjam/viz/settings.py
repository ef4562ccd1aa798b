"""What the run's figure and replay draw beside the logs: the area, the antenna, the names and
the metrics' parameters, built from the scenario by
:func:`trackjam.simulation.build.figure_settings` (the figures never read the configuration)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from trackjam.radio.antenna import AntennaModel


@dataclass(frozen=True)
class FigureSettings:
    name: str  # the scenario's name, in the titles
    solver: str  # control.solver, in the titles
    low: np.ndarray  # (3,) the area's lower corner [m]
    high: np.ndarray  # (3,) the area's upper corner [m]
    antenna: AntennaModel  # the cones (h_a, theta_a / 2) and delta, in watts and radians
    opening_angle_deg: float  # theta_a as configured [deg], for the captions
    interference_limit_db: float  # delta as configured [dBW], for the captions and panel (d)
    power_levels_db: tuple[float | str, ...]  # L as configured [dBW], "off" for 0 W
    ospa_order: float  # p of OSPA
    ospa_cutoff: float  # c of OSPA [m]
    gate: float  # metrics.gate, track quality judged by the truth [m]


def save_figure(fig, path, **kwargs) -> None:
    """``fig.savefig(path, dpi=110, **kwargs)`` without matplotlib's "constrained_layout not
    applied" warning, given when the panels leave no room for one of them (64 agents in the
    legends, a 100-character target id): the figure is written all the same, and a raw warning is
    no line of ours on stderr."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "constrained_layout not applied", UserWarning)
        fig.savefig(path, dpi=110, **kwargs)
