"""The experiments: which configurations are compared on the same trials, and the scenario of
each (configuration, trial).

The paper's (Section VI), on its trial draw (target uniform in the area, pursuers in a 20 m ball
around it) and the ``paper-fig3`` settings without Fig. 3's occlusions:

- ``table1``: the 8 configurations of Table I (Fig. 4): 11 mobility controls (Delta_R = [3] m,
  N_phi = 4, N_theta = 8; the 3 m is ours, docs/model.md) or 79 controls (Delta_R = [1, 3, 5] m,
  N_phi = N_theta = 8), times theta_a in {60, 80, 100, 120} deg.
- ``constraints``: Fig. 5, the interference constraints of Eq. (13) enabled and disabled.
- ``solvers`` (beyond the paper): the paper's GRASP against the exact optimum of Eqs. (12)-(13).

Ours, on Fig. 3 itself (the ``paper-fig3`` scenario with its occlusion, the exact solver), trial
k varying only the seed, so the truth's random walk and every other random choice change from
trial to trial while every configuration of trial k sees the same truth:

- ``holding``: how well the team holds the target, judged by the truth, for the paper's
  behaviour and each pursuit option (:data:`HOLDING_VARIANTS`), beside the clairvoyant ceiling;
- ``comms``: the distributed team (``pointing: aim``) under lost and late messages and failures;
- ``oracles``: the preset ``pursuit`` beside the same preset told what no real team knows
  (``oracle.*``, :data:`ORACLE_VARIANTS`): what each piece of knowledge would be worth.

Ours, on several targets (the ``swarm-3`` preset's settings, the targets' jamming response on):

- ``swarm``: K targets x N agents (default K = 1..4, N = 3..6), one configuration per cell,
  trial k drawn per cell by :mod:`trackjam.experiments.swarm`, plus the K = 1 cells on the
  one-target engine.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from trackjam.config import (
    Scenario,
    apply_overrides,
    load_scenario,
    load_scenario_data,
    scenario_to_dict,
    set_dotted,
    validate_scenario,
)
from trackjam.config.loading import SET_SHOWN, overridden_keys
from trackjam.errors import ConfigError, shortened
from trackjam.experiments.experiment import (  # noqa: F401  (the experiments' vocabulary, from here too)
    BASE_PRESET,
    DRAW,
    FIG4_PANELS,
    SEED,
    SWARM,
    Configuration,
    Experiment,
    Panel,
)
from trackjam.experiments.summary import COUNTS, METRICS, QUALITY, Metric
from trackjam.experiments.swarm import draw_swarm, swarm_experiment, swarm_fields
from trackjam.experiments.trials import TrialDraw, draw_trial, simulation_seed, trial_fields
from trackjam.simulation.build import displacements as scenario_displacements


CONTROLS_11 = {"agents.radial_steps": [3.0], "agents.n_inclination": 4, "agents.n_azimuth": 8}
CONTROLS_79 = {"agents.radial_steps": [1.0, 3.0, 5.0], "agents.n_inclination": 8, "agents.n_azimuth": 8}

FIG5_PANELS = (
    Panel("(a) jamming incidents", "incidents per trial per agent", (("incidents", None),)),
    Panel("(b) agent received power", "W", (("agent_received_w", None),)),
    Panel("(c) target received power", "W", (("target_received_w", None),)),
    Panel("(d) tracking error", "OSPA [m]", (("ospa", None),)),
)
# ours: track quality judged by the truth beside the ceiling, re-acquisition, OSPA, incidents
HOLDING_PANELS = (
    Panel("(a) track quality judged by the truth", "share of detectable steps",
          (("held", "held"), ("false_track", "false track"), ("missed", "missed"),
           ("ceiling", "ceiling: clairvoyant chaser within 8 m")), log=False, ceiling=1.0),
    Panel("(b) held again after the last hidden spell", "share of trials\n(Clopper-Pearson 95%)",
          (("reacquired", None),), ceiling=1.0,
          empty="no trial had a hidden spell\nfollowed by detectable steps"),
    Panel("(c) tracking error", "OSPA [m]", (("ospa", None),)),
    Panel("(d) jamming incidents", "incidents per trial per agent", (("incidents", None),)),
)
# the columns of holding and comms: track quality first, then what the paper measures of it
HOLDING_METRICS: tuple[Metric, ...] = tuple(
    m for stem in ("held", "false_track", "missed", "ospa", "incidents", "ceiling") for m in METRICS + QUALITY if m[0] == stem
)




ANGLES = (60.0, 80.0, 100.0, 120.0)  # Table I's opening angles theta_a [deg]


def _table1() -> Experiment:
    configurations = []
    for controls, moves in ((11, CONTROLS_11), (79, CONTROLS_79)):
        for theta_a in ANGLES:
            i = len(configurations) + 1
            configurations.append(
                Configuration(i, f"{controls} controls, {theta_a:g} deg", {**moves, "antenna.opening_angle_deg": theta_a})
            )
    # paired: 11 against 79 controls at each angle; along the angles for each control set
    pairs = [(i, i + 4, f"{a:g} deg: 11 -> 79 controls") for i, a in enumerate(ANGLES, start=1)]
    for controls, first in ((11, 1), (79, 5)):
        steps = [(first + j, first + j + 1) for j in range(len(ANGLES) - 1)] + [(first, first + len(ANGLES) - 1)]
        pairs += [(a, b, f"{controls} controls: {ANGLES[a - first]:g} -> {ANGLES[b - first]:g} deg") for a, b in steps]
    return Experiment(
        "table1",
        "Table I / Fig. 4: 11 or 79 mobility controls x opening angle 60, 80, 100, 120 deg",
        tuple(configurations),
        "fig4.png",
        xlabel="configuration (Table I): 1-4: 11 controls, 5-8: 79 controls; theta_a 60/80/100/120 deg",
        counts=COUNTS,
        pairs=tuple(pairs),
    )


def _leaves(data: Any, prefix: str = "") -> dict[str, Any]:
    """A nested mapping as dotted keys -> values (lists are values)."""
    if not isinstance(data, dict):
        return {prefix: data}
    out: dict[str, Any] = {}
    for k, v in data.items():
        out |= _leaves(v, f"{prefix}{k}.") if isinstance(v, dict) and v else {f"{prefix}{k}": v}
    return out


def preset_settings(name: str) -> dict[str, Any]:
    """The dotted keys in which preset ``name`` differs from the base preset, both resolved: a
    configuration with these settings is that preset."""
    base, mine = (_leaves(scenario_to_dict(load_scenario(p))) for p in (BASE_PRESET, name))
    return {k: v for k, v in mine.items() if k not in ("name", "seed", "steps") and base.get(k, object()) != v}


# The preset `pursuit` as settings on the base preset: the last row of `holding`, the first of `oracles`
PURSUIT_SETTINGS = preset_settings("pursuit")

# The rows of `holding`, in order: (label, dotted keys). The paper's behaviour with the paper's
# idealised pointing and with the pointing a real team has, then each option beyond the paper
# alone on top of `pointing: aim`.
HOLDING_VARIANTS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("paper, pointing: truth", {"antenna.pointing": "truth"}),
    ("paper, pointing: aim", {"antenna.pointing": "aim"}),
    ("aim + measurement birth", {"antenna.pointing": "aim", "filter.birth": "measurement"}),
    ("aim + plan over the belief", {"antenna.pointing": "aim", "control.plan_over": "belief"}),
    ("aim + lead 0.5 step", {"antenna.pointing": "aim", "control.lead": 0.5}),
    ("aim + intercept horizon 5", {"antenna.pointing": "aim", "control.horizon": 5}),
    ("aim + search reseed on evidence", {"antenna.pointing": "aim", "fusion.search_reseed": "evidence"}),
    ("aim + scans shared", {"antenna.pointing": "aim", "fusion.share": "scans"}),
    ("aim + hidden-target mode", {"antenna.pointing": "aim", "filter.visibility": {"hide": 0.05, "reappear": 0.25}}),
    ("aim + report spread <= 8 m", {"antenna.pointing": "aim", "fusion.report_spread": 8.0}),
    ("aim + scans shared + hidden-target mode", {"antenna.pointing": "aim", "fusion.share": "scans",
                                                  "filter.visibility": {"hide": 0.05, "reappear": 0.25}}),
    ("aim + cue with the target's velocity", {"antenna.pointing": "aim", "filter.cue.velocity": "target"}),
    ("aim + estimate at the mode", {"antenna.pointing": "aim", "filter.mode": {"radius": 5.0, "mass": 0.2}}),
    ("aim + plan over the belief while it spreads > 8 m", {"antenna.pointing": "aim", "control.plan_over": "belief",
                                                           "control.belief_spread": 8.0}),
    ("aim + close in below Xi 0.05", {"antenna.pointing": "aim", "control.close_in": 0.05}),
    ("preset pursuit", PURSUIT_SETTINGS),
)

# The rows of `oracles`: the preset, then the preset told what no real team knows (oracle.*,
# diagnostic), each measuring what that knowledge is worth to re-acquisition after the occlusion.
ORACLE_VARIANTS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("preset pursuit", PURSUIT_SETTINGS),
    ("told the true state before it hides", {**PURSUIT_SETTINGS, "oracle.state_before_hiding": True}),
    ("told where it reappears (1 step)", {**PURSUIT_SETTINGS, "oracle.truth_after_hiding": 1}),
    ("told where it is on 3 steps after it reappears", {**PURSUIT_SETTINGS, "oracle.truth_after_hiding": 3}),
    ("told where it is on 3 steps after each detection", {**PURSUIT_SETTINGS, "oracle.follow_up": 3}),
    ("filters told the hidden scans are empty", {**PURSUIT_SETTINGS, "oracle.empty_hidden_scans": True}),
    ("filters' mean moved onto the true state before it hides", {**PURSUIT_SETTINGS, "oracle.mean_before_hiding": True}),
    ("antennas pointed at it on 1 step after it reappears", {**PURSUIT_SETTINGS, "oracle.point_after_hiding": 1}),
)

# The rows of `comms`: the fault model of the distributed team, one fault at a time.
COMMS_VARIANTS: tuple[tuple[str, dict[str, Any]], ...] = (
    *((f"loss {p:g}", {"comms.loss": p}) for p in (0.0, 0.1, 0.3, 0.5, 1.0)),
    ("delay 1 step", {"comms.delay_steps": 1}),
    ("delay 1 step, late posteriors dropped", {"comms.delay_steps": 1, "comms.stale": "drop"}),
    ("agent 0's publisher fails at step 10", {"comms.failures": [{"agent": 0, "step": 10, "mode": "publisher"}]}),
    ("agent 0 breaks down at step 10", {"comms.failures": [{"agent": 0, "step": 10, "mode": "breakdown"}]}),
)


def _variants(rows: tuple[tuple[str, dict[str, Any]], ...]) -> tuple[Configuration, ...]:
    return tuple(Configuration(i, label, settings) for i, (label, settings) in enumerate(rows, start=1))


def _against(reference: int, rows: tuple[tuple[str, dict[str, Any]], ...]) -> list[tuple[int, int, str]]:
    """Pairs of every other row against row ``reference`` (1-based), labelled 'REF -> ROW'."""
    ref = rows[reference - 1][0]
    return [(reference, i, f"{ref} -> {label}") for i, (label, _) in enumerate(rows, start=1) if i != reference]


def _on_fig3(name: str, description: str, rows: tuple[tuple[str, dict[str, Any]], ...], pairs,
             settings: dict[str, Any] | None = None) -> Experiment:
    """An experiment of ours on Fig. 3 itself (SEED trials, the exact solver and ``settings``),
    one configuration per row, with the track quality, re-acquisition and the figure of `holding`."""
    return Experiment(name, description, _variants(rows), f"{name}.png", panels=HOLDING_PANELS,
                      metrics=HOLDING_METRICS, counts=COUNTS, trials=SEED,
                      base_settings={"control.solver": "exact", **(settings or {})}, pairs=tuple(pairs))


def against_preset(name: str, description: str, label: str, settings: dict[str, Any], pair: str,
                   preset: str = "pursuit") -> Experiment:
    """``preset`` against ``preset`` with ``settings`` (labelled ``label``), paired (``pair``) on the
    same SEED trials, with the track quality, re-acquisition and the figure of `holding`: the
    shape of the docs scripts that measure one change to the preset (docs/search_options.py,
    docs/birth_mixed.py), which register it under ``name`` and run it."""
    return Experiment(
        name, description, (Configuration(1, preset, {}), Configuration(2, label, settings)), f"{name}.png",
        trials=SEED, preset=preset, pairs=((1, 2, pair),), panels=HOLDING_PANELS, metrics=HOLDING_METRICS,
        counts=COUNTS,
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
        counts=COUNTS,
        pairs=((1, 2, "constraints on -> off"),),
    ),
    "solvers": Experiment(
        "solvers",
        "beyond the paper: GRASP (the paper's solver) against the exact optimum",
        (
            Configuration(1, "grasp", {"control.solver": "grasp"}),
            Configuration(2, "exact", {"control.solver": "exact"}),
        ),
        "solvers.png",
        counts=COUNTS,
        pairs=((1, 2, "grasp -> exact"),),
    ),
    "holding": _on_fig3(
        "holding", "ours: holding the target on Fig. 3 (exact solver), judged by the truth", HOLDING_VARIANTS,
        # every row against the paper's team with aim pointing; the preset against pointing: truth
        (*_against(2, HOLDING_VARIANTS), (1, len(HOLDING_VARIANTS), "paper, pointing: truth -> preset pursuit")),
    ),
    "comms": _on_fig3(
        "comms", "ours: the distributed team on Fig. 3 (exact, pointing: aim) under message faults", COMMS_VARIANTS,
        _against(1, COMMS_VARIANTS),  # every fault against the faultless team
        {"antenna.pointing": "aim"},
    ),
    "oracles": _on_fig3(
        "oracles",
        "ours: what the preset pursuit would re-acquire after the Fig. 3 occlusion if told what no real team knows",
        ORACLE_VARIANTS, _against(1, ORACLE_VARIANTS),  # every oracle against the preset
    ),
}

EXPERIMENTS["swarm"] = swarm_experiment()

# Keys a trial sets itself: a --set of these (or of a section holding them) is refused.
_SEED_TRIAL_KEYS = ("steps", "seed")
_DRAW_TRIAL_KEYS = (
    *_SEED_TRIAL_KEYS,
    "target.initial",
    "target.appears",
    "target.disappears",
    "target.occlusions",
    "target.stochastic",
    "agents.initial",
    "agents.initial_aim",
)
_SWARM_TRIAL_KEYS = (*_SEED_TRIAL_KEYS, "target", "targets", "agents.initial", "agents.initial_aim")


def get_experiment(name: str, grid: str | None = None) -> Experiment:
    """Experiment ``name``; ``grid`` (TARGETSxAGENTS) only for ``swarm``."""
    try:
        experiment = EXPERIMENTS[name]
    except KeyError:
        import difflib

        close = difflib.get_close_matches(str(name).lower(), list(EXPERIMENTS), n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ConfigError(f"unknown experiment {shortened(name, 40)!r}{hint}; choose one of: {', '.join(EXPERIMENTS)}") from None
    if grid is None:
        return experiment
    if experiment.trials != SWARM:
        raise ConfigError(f"--grid: experiment {name} has no grid (only swarm has)")
    return swarm_experiment(grid)


def _overlaps(a: str, b: str) -> bool:
    return a == b or a.startswith(b + ".") or b.startswith(a + ".")


def _owned(experiment: Experiment, key: str) -> str | None:
    """The key every trial of ``experiment`` sets that ``key`` is, holds or lies in; None if none."""
    return next((k for k in owned_keys(experiment) if _overlaps(key, k)), None)


def check_overrides(experiment: Experiment, overrides: list[str]) -> None:
    """Refuse ``--set`` keys that the trials or the experiment's sweep set themselves."""
    for item in overrides:
        key = item.partition("=")[0].strip()
        shown = shortened(key, SET_SHOWN)  # a key of 100 kB was echoed whole
        if experiment.trials != SWARM and _overlaps(key, "targets"):  # else: "give target or targets"
            raise ConfigError(f"--set {shown}: experiment {experiment.name} draws one target per trial; "
                              "several targets: trackjam experiment swarm")
        if key_owned := _owned(experiment, key):
            hint = " (use --steps)" if key_owned == "steps" else " (use --seed)" if key_owned == "seed" else ""
            raise ConfigError(f"--set {shown}: set by every trial of an experiment, not settable{hint}")
        for swept in sorted(experiment.swept_keys):
            if _overlaps(key, swept):
                raise ConfigError(f"--set {shown}: swept by experiment {experiment.name} ({swept})")


def _check_own_settings(experiment: Experiment) -> None:
    """Refuse (ValueError) a hand-built experiment whose settings set a key its trials set
    themselves: a configuration's ``steps`` had silently replaced --steps, its ``seed`` done
    nothing."""
    for where, settings in [("base_settings", experiment.base_settings)] + [
            (f"configuration {c.index}", c.settings) for c in experiment.configurations]:
        for key in settings:
            if _owned(experiment, key):
                raise ValueError(f"experiment {experiment.name}: {where} sets {key}, which every trial sets itself "
                                 "(--steps and --seed set the steps and the seed)")


def base_data(experiment: Experiment, steps: int, overrides: list[str] | None = None) -> dict:
    """The experiment's preset (the paper's settings, without Fig. 3's occlusions for the paper's
    trial draw), its own settings, ``steps`` steps, and the user's overrides."""
    overrides = list(overrides or [])
    check_overrides(experiment, overrides)
    _check_own_settings(experiment)
    data, _ = load_scenario_data(experiment.preset)
    data["steps"] = steps
    if experiment.trials == DRAW:
        data.setdefault("target", {})["occlusions"] = []
    for key, value in experiment.base_settings.items():
        set_dotted(data, key, value)
    # trials already run side by side: each one's GRASP searches run one after another
    data.setdefault("control", {}).setdefault("grasp", {})["threads"] = 1
    return apply_overrides(data, overrides)


def trial_scenario(
    experiment: Experiment, base: dict, configuration: Configuration, draw: TrialDraw, seed: int,
    overrides: list[str] | None = None,
) -> Scenario:
    """The validated scenario of trial ``draw`` under ``configuration``: the draw's start (a DRAW
    experiment; a SEED experiment keeps Fig. 3's) and a seed of (experiment seed, trial) alone,
    the same under every configuration. A problem with a key one of ``overrides`` set (a
    ``--set`` that clashes with a configuration's settings) is blamed on that ``--set`` item."""
    data = apply_overrides(base, [])
    placed = trial_fields(draw) if experiment.trials == DRAW else {}
    for key, value in {**configuration.settings, **placed}.items():
        set_dotted(data, key, value)
    # common random numbers: trial k's simulation seed is the same under every configuration
    # (configuration 0 is no configuration's), so configurations are compared on the same truth
    data["seed"] = simulation_seed(seed, 0, draw.index)
    data["name"] = f"{experiment.name}-c{configuration.index}-t{draw.index}"
    return validate_scenario(data, f"experiment {experiment.name}, configuration {configuration.index}",
                             overridden_keys(overrides))


def owned_keys(experiment: Experiment) -> tuple[str, ...]:
    """The keys every trial of ``experiment`` sets itself (a --set of them is refused)."""
    return {DRAW: _DRAW_TRIAL_KEYS, SEED: _SEED_TRIAL_KEYS, SWARM: _SWARM_TRIAL_KEYS}[experiment.trials]


def _placed_inside(base: dict, owned: tuple[str, ...]) -> dict:
    """``base`` with the starting positions its trials place themselves (``owned``) moved inside
    its area, apart from one another: the preset's own (Fig. 3's agents at 30-40 m) are never
    simulated, and lying outside a smaller ``--set area`` they made every such experiment
    refuse it, with no --set to mend it. An area that is not three numbers per corner is left
    for the validation to name."""
    data = apply_overrides(base, [])
    area = data.get("area") or {}
    try:
        low = np.asarray(area.get("low", (0.0, 0.0, 0.0)), dtype=float).reshape(3)
        high = np.asarray(area.get("high", (100.0, 100.0, 100.0)), dtype=float).reshape(3)
    except (TypeError, ValueError, AttributeError):
        return data

    def at(*fractions: float) -> list[float]:
        return [float(v) for v in low + (high - low) * np.asarray(fractions)]

    agents = data.get("agents")
    if "agents.initial" in owned and isinstance(agents, dict) and isinstance(agents.get("initial"), list):
        n = len(agents["initial"])
        agents["initial"] = [at((i + 1) / (n + 1), (i + 1) / (n + 1), 0.25) for i in range(n)]
    if "agents.initial_aim" in owned and isinstance(agents, dict) and agents.get("initial_aim") is not None:
        agents["initial_aim"] = at(0.5, 0.5, 0.5)
    targets = [data.get("target")] if any(k in owned for k in ("target", "target.initial")) else []
    if "targets" in owned and isinstance(data.get("targets"), list):
        targets += data["targets"]
    targets = [t for t in targets if isinstance(t, dict) and isinstance(t.get("initial"), list)]
    for k, t in enumerate(targets):
        t["initial"] = at(0.5, (k + 1) / (len(targets) + 1), 0.75) + list(t["initial"][3:])
    return data


def base_scenario(base: dict, preset: str = BASE_PRESET, overrides: list[str] | None = None,
                  owned: tuple[str, ...] = ()) -> Scenario:
    """The base scenario validated (so a bad --set fails here, before any trial); a problem with
    a key one of ``overrides`` set is blamed on that ``--set`` item, as `trackjam run` does.
    The starting positions the trials place themselves (``owned``, :func:`owned_keys`) are moved
    inside the area first (:func:`_placed_inside`)."""
    return validate_scenario(_placed_inside(base, owned) if owned else base,
                             f"base scenario of the experiment (preset {preset} with --set)", overridden_keys(overrides))


def draw_for(base: dict, seed: int, k: int, space: Scenario | None = None) -> TrialDraw:
    """Trial k's draw in the area of ``space``, the validated base scenario (validated here when
    not given, so a bad --set fails here)."""
    s = space if space is not None else base_scenario(base)
    return draw_trial(seed, k, s.area.low, s.area.high, s.n_agents, s.filter.birth_speed)


def swarm_scenario(experiment: Experiment, space: Scenario, base: dict, configuration: Configuration, k: int,
                   seed: int) -> Scenario:
    """Trial k of a swarm cell: ``space`` (the validated base) gives the area and v_b of the draw;
    the seed is trial k's in every cell, so the truth's and agents' streams are shared."""
    n_targets, n_agents = configuration.cell
    draw = draw_swarm(seed, k, n_targets, n_agents, space.area.low, space.area.high, space.filter.birth_speed)
    data = apply_overrides(base, [])
    for key, value in swarm_fields(draw, configuration.one_target).items():
        set_dotted(data, key, value)
    data = {key: value for key, value in data.items() if value is not None or key not in ("target", "targets")}
    data["seed"] = simulation_seed(seed, 0, k)
    data["name"] = f"{experiment.name}-c{configuration.index}-t{k}"
    return validate_scenario(data, f"experiment {experiment.name}, {configuration.label}")


def configuration_columns(s: Scenario) -> dict[str, Any]:
    """The parameters summary.csv reports for a configuration."""
    return {
        "n_controls": int(len(scenario_displacements(s))),
        "opening_angle_deg": float(s.antenna.opening_angle_deg),
        "constraints": bool(s.control.constraints),
        "solver": s.control.solver,
    }
