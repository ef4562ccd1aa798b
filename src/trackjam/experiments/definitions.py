"""The experiments: which configurations are compared on the same trials, and the scenario of
each (configuration, trial).

- ``table1``: the 8 configurations of Table I (Fig. 4): 11 mobility controls (Delta_R = [3] m,
  N_phi = 4, N_theta = 8; the 3 m is ours, docs/model.md) or 79 controls (Delta_R = [1, 3, 5] m,
  N_phi = N_theta = 8), times theta_a in {60, 80, 100, 120} deg.
- ``constraints``: Fig. 5, the interference constraints of Eq. (13) enabled and disabled.
- ``solvers`` (beyond the paper): the paper's GRASP against the exact optimum of Eqs. (12)-(13).

The base scenario is the paper's settings (Section VI-A; the ``paper-fig3`` preset) without
Fig. 3's occlusions, with the experiment's number of steps and the user's ``--set`` overrides.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from trackjam.config import (
    Scenario,
    apply_overrides,
    load_scenario_data,
    set_dotted,
    validate_scenario,
)
from trackjam.errors import ConfigError
from trackjam.experiments.summary import METRICS, Metric
from trackjam.experiments.trials import TrialDraw, draw_trial, simulation_seed, trial_fields
from trackjam.simulation.build import displacements as scenario_displacements

BASE_PRESET = "paper-fig3"

CONTROLS_11 = {"agents.radial_steps": [3.0], "agents.n_inclination": 4, "agents.n_azimuth": 8}
CONTROLS_79 = {"agents.radial_steps": [1.0, 3.0, 5.0], "agents.n_inclination": 8, "agents.n_azimuth": 8}


@dataclass(frozen=True)
class Configuration:
    """One column of a comparison: ``index`` is 1-based (Table I's "Config. #")."""

    index: int
    label: str
    settings: dict[str, Any] = field(default_factory=dict)  # dotted scenario keys


@dataclass(frozen=True)
class Panel:
    """One panel of an experiment's figure: a bar per configuration and series, with its 95 %
    interval, clipped at ``floor`` (the metric's physical lower bound)."""

    title: str
    ylabel: str
    series: tuple[tuple[str, str | None], ...]  # (metric stem, legend or None)
    floor: float = 0.0


FIG4_PANELS = (
    Panel("(a) jamming incidents", "incidents per trial per agent", (("incidents", None),)),
    Panel("(b) received power", "W", (("target_received_w", "target"), ("agent_received_w", "agents"))),
    Panel("(c) transmit power", "W per agent per step", (("transmit_w", None),)),
    Panel("(d) tracking error", "OSPA [m]", (("ospa", None),)),
)
FIG5_PANELS = (
    Panel("(a) jamming incidents", "incidents per trial per agent", (("incidents", None),)),
    Panel("(b) agent received power", "W", (("agent_received_w", None),)),
    Panel("(c) target received power", "W", (("target_received_w", None),)),
    Panel("(d) tracking error", "OSPA [m]", (("ospa", None),)),
)


@dataclass(frozen=True)
class Experiment:
    """A comparison of ``configurations`` on the same trials. It names what it summarises
    (``metrics``: summary.csv's columns, read from each trial's record) and what its figure
    shows (``panels``, over those metrics); both default to Fig. 4's."""

    name: str
    description: str
    configurations: tuple[Configuration, ...]
    figure: str  # file name of its figure in OUT
    panels: tuple[Panel, ...] = FIG4_PANELS
    metrics: tuple[Metric, ...] = METRICS
    xlabel: str = ""  # below the figure; ticks are the configurations' labels unless it is set

    def __post_init__(self) -> None:
        stems = {m[0] for m in self.metrics}
        unknown = [stem for p in self.panels for stem, _ in p.series if stem not in stems]
        if unknown:
            raise ValueError(f"experiment {self.name}: panels show {unknown}, which are not among its metrics")

    @property
    def swept_keys(self) -> set[str]:
        return {k for c in self.configurations for k in c.settings}


def _table1() -> Experiment:
    configurations = []
    for controls, moves in ((11, CONTROLS_11), (79, CONTROLS_79)):
        for theta_a in (60.0, 80.0, 100.0, 120.0):
            i = len(configurations) + 1
            configurations.append(
                Configuration(i, f"{controls} controls, {theta_a:g} deg", {**moves, "antenna.opening_angle_deg": theta_a})
            )
    return Experiment(
        "table1",
        "Table I / Fig. 4: 11 or 79 mobility controls x opening angle 60, 80, 100, 120 deg",
        tuple(configurations),
        "fig4.png",
        xlabel="configuration (Table I): 1-4: 11 controls, 5-8: 79 controls; theta_a 60/80/100/120 deg",
    )


EXPERIMENTS: dict[str, Experiment] = {
    "table1": _table1(),
    "constraints": Experiment(
        "constraints",
        "Fig. 5: interference constraints (Eq. 13) enabled and disabled",
        (
            Configuration(1, "constraints on", {"control.constraints": True}),
            Configuration(2, "constraints off", {"control.constraints": False}),
        ),
        "fig5.png",
        panels=FIG5_PANELS,
    ),
    "solvers": Experiment(
        "solvers",
        "beyond the paper: GRASP (the paper's solver) against the exact optimum",
        (
            Configuration(1, "grasp", {"control.solver": "grasp"}),
            Configuration(2, "exact", {"control.solver": "exact"}),
        ),
        "solvers.png",
    ),
}

# Keys a trial sets itself: a --set of these (or of a section holding them) is refused.
_TRIAL_KEYS = (
    "steps",
    "seed",
    "target.initial",
    "target.appears",
    "target.disappears",
    "target.occlusions",
    "target.stochastic",
    "agents.initial",
    "agents.initial_aim",
)


def get_experiment(name: str) -> Experiment:
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ConfigError(f"unknown experiment {name!r}; choose one of: {', '.join(EXPERIMENTS)}") from None


def _overlaps(a: str, b: str) -> bool:
    return a == b or a.startswith(b + ".") or b.startswith(a + ".")


def check_overrides(experiment: Experiment, overrides: list[str]) -> None:
    """Refuse ``--set`` keys that the trial draw or the experiment's sweep sets itself."""
    for item in overrides:
        key = item.partition("=")[0].strip()
        for owned in _TRIAL_KEYS:
            if _overlaps(key, owned):
                hint = " (use --steps)" if owned == "steps" else " (use --seed)" if owned == "seed" else ""
                raise ConfigError(f"--set {key}: set by every trial of an experiment, not settable{hint}")
        for swept in sorted(experiment.swept_keys):
            if _overlaps(key, swept):
                raise ConfigError(f"--set {key}: swept by experiment {experiment.name} ({swept})")


def base_data(experiment: Experiment, steps: int, overrides: list[str] | None = None) -> dict:
    """The paper's settings without occlusions, ``steps`` steps, and the user's overrides."""
    overrides = list(overrides or [])
    check_overrides(experiment, overrides)
    data, _ = load_scenario_data(BASE_PRESET)
    data["steps"] = steps
    data.setdefault("target", {})["occlusions"] = []
    # trials already run side by side: each one's GRASP searches run one after another
    data.setdefault("control", {}).setdefault("grasp", {})["threads"] = 1
    return apply_overrides(data, overrides)


def trial_scenario(
    experiment: Experiment, base: dict, configuration: Configuration, draw: TrialDraw, seed: int
) -> Scenario:
    """The validated scenario of trial ``draw`` under ``configuration``."""
    data = apply_overrides(base, [])
    for key, value in {**configuration.settings, **trial_fields(draw)}.items():
        set_dotted(data, key, value)
    data["seed"] = simulation_seed(seed, configuration.index, draw.index)
    data["name"] = f"{experiment.name}-c{configuration.index}-t{draw.index}"
    return validate_scenario(data, f"experiment {experiment.name}, configuration {configuration.index}")


def draw_for(base: dict, seed: int, k: int) -> TrialDraw:
    """Trial k's draw in the base scenario's area (validated first, so a bad --set fails here)."""
    s = validate_scenario(base, f"base scenario of the experiment (preset {BASE_PRESET} with --set)")
    return draw_trial(seed, k, s.area.low, s.area.high, s.n_agents, s.filter.birth_speed)


def configuration_columns(s: Scenario) -> dict[str, Any]:
    """The parameters summary.csv reports for a configuration."""
    return {
        "n_controls": int(len(scenario_displacements(s))),
        "opening_angle_deg": float(s.antenna.opening_angle_deg),
        "constraints": bool(s.control.constraints),
        "solver": s.control.solver,
    }
