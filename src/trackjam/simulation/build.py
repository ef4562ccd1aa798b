"""The one place a :class:`Scenario` is read for a run: it becomes the components and the small
settings objects the step's stages take, and what the figures draw.

Outside the configuration itself, this module, the command line and the experiments, no module
imports :mod:`trackjam.config` but for type hints (``tests/test_layout.py``): a module that is
handed a scenario (the engine, the environment, the output folder, the benchmarks) passes it on
to a function here.
``load_scenario`` is imported here for them, and for the package's public ``trackjam.load_scenario``."""

from __future__ import annotations

import os
import typing
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Callable

import numpy as np

from trackjam.config import Scenario, load_scenario, scenario_to_yaml, validate_scenario  # noqa: F401  (load_scenario: handed on)
from trackjam.control.planning import PlanSettings
from trackjam.control.pursuit import AimSettings
from trackjam.config.limits import MAX_SEED, threads_variable
from trackjam.errors import ConfigError
from trackjam.estimation.bernoulli import BernoulliFilter, FilterParams
from trackjam.estimation.failsafe import FailSafe
from trackjam.estimation.lmb import LMBParams
from trackjam.radio.antenna import AntennaModel
from trackjam.simulation.team import TeamSettings
from trackjam.viz.settings import FigureSettings
from trackjam.world.moves import displacement_set
from trackjam.world.target import Response, TargetParams

if TYPE_CHECKING:
    from trackjam.config.model import Oracle


def default_threads(n_agents: int) -> int:
    """One thread per agent's GRASP search, up to the CPU count, or as many as the environment's
    TRACKJAM_THREADS says (a whole number in [1, 1024]; anything else is refused in one line)."""
    env = threads_variable("TRACKJAM_THREADS", "one per agent up to the CPU count")
    return env if env is not None else max(1, min(n_agents, os.cpu_count() or 1))


def _home(r, low: np.ndarray) -> np.ndarray:
    return np.asarray(r.home if r.home is not None else (low[0], low[1], low[2]), dtype=float)


def target_params(s: Scenario) -> TargetParams:
    tg, low = s.target, np.asarray(s.area.low, dtype=float)
    r = tg.response
    response = None if r is None else Response(
        threshold_w=10 ** (r.threshold_db / 10), steps=r.steps, action=r.action, speed=r.speed, home=_home(r, low),
    )
    return TargetParams(
        low=low,
        high=np.asarray(s.area.high, dtype=float),
        initial=None if tg.initial is None else np.asarray(tg.initial, dtype=float),
        draw_speed=float(s.filter.birth_speed),  # a random draw is drawn as the filters' birth is
        appears=tg.appears,
        disappears=tg.disappears,
        occlusions=tuple(tuple(o) for o in tg.occlusions),
        accel_var=float(tg.accel_var),
        stochastic=None if tg.stochastic is None else (tg.stochastic.birth_prob, tg.stochastic.survival_prob),
        response=response,
        walls=tg.walls,
    )


def targets_params(s: Scenario) -> list[TargetParams]:
    """Every truth target's parameters, in the order of ``targets`` (one for ``target``): each is
    :func:`target_params` of the scenario with that target as its one target."""
    return [target_params(s.model_copy(update={"target": tg})) for tg in s.target_list]


def target_ids(s: Scenario) -> list[int | str]:
    """The targets' ids, in the order of :func:`targets_params` (0 for the one ``target``)."""
    return [tg.id for tg in s.target_list]


def antenna_model(s: Scenario) -> AntennaModel:
    """The conic antenna of Eqs. (9)-(10) and (13), in watts and radians."""
    a = s.antenna
    return AntennaModel(
        height=float(a.height),
        half_angle=float(np.deg2rad(a.opening_angle_deg) / 2),
        r0=float(a.r0),
        n_e=float(a.path_loss_exponent),
        p_d_max=float(a.p_d_max),
        levels_w=np.asarray(a.levels_w, dtype=np.float64),
        delta_w=float(a.delta_w),
    )


def filter_params(s: Scenario) -> FilterParams:
    f = s.filter
    return FilterParams(
        birth_prob=float(f.birth_prob), survival_prob=float(f.survival_prob), particles=int(f.particles),
        birth_particles=int(f.birth_particles), birth=f.birth, birth_mix=float(f.birth_mix),
        measurement_birth_speed=float(f.measurement_birth_speed), birth_speed=float(f.birth_speed),
        accel_var=s.filter_accel_var, walls=f.walls, low=np.asarray(s.area.low, dtype=float),
        high=np.asarray(s.area.high, dtype=float), noise_std=np.asarray(s.sensor.noise_std, dtype=float),
        clutter_rate=float(s.sensor.clutter_rate),
        visibility=None if f.visibility is None else (float(f.visibility.hide), float(f.visibility.reappear)),
        mode=None if f.mode is None else (float(f.mode.radius), float(f.mode.mass)),
        response=fail_safe(s), reserve_memory=int(f.reserve_memory), velocity_jitter=float(f.velocity_jitter),
        visibility_per_particle=f.visibility is not None and bool(f.visibility.per_particle),
        team_proposals=bool(f.team_proposals),
    )


def fail_safe(s: Scenario) -> FailSafe | None:
    """``filter.response``: the fail-safe the filters expect (None: Eq. (1) always, the paper)."""
    r, low = s.filter.response, np.asarray(s.area.low, dtype=float)
    if r is None:
        return None
    return FailSafe(threshold_w=10 ** (r.threshold_db / 10), steps=int(r.steps), action=r.action, speed=float(r.speed),
                    home=_home(r, low), ground=float(low[2]), hedge=float(r.hedge))


def make_filter(s: Scenario, rng: np.random.Generator, **options) -> BernoulliFilter:
    """One agent's filter for scenario ``s`` drawing from ``rng`` (``options``: the filter's
    keyword arguments)."""
    return BernoulliFilter(filter_params(s), antenna_model(s), rng, **options)


def displacements(s: Scenario) -> np.ndarray:
    """Eq. (3)'s displacement set of the scenario, hover first."""
    a = s.agents
    return displacement_set(a.radial_steps, a.n_inclination, a.n_azimuth)


def seed_tree(seed: int, n_agents: int) -> tuple[np.random.SeedSequence, list[list[np.random.SeedSequence]],
                                                 np.random.SeedSequence]:
    """One root seed -> the truth's stream, three streams per agent (filter, sensor, plan) and
    the message exchange's stream (losses)."""
    root = np.random.SeedSequence(seed)
    truth_seed, agents_seed, comms_seed = root.spawn(3)
    return truth_seed, [s.spawn(3) for s in agents_seed.spawn(n_agents)], comms_seed


@dataclass(frozen=True)
class Components:
    name: str
    steps: int
    seed: int
    n_agents: int
    initial_positions: np.ndarray  # (N, 3) u_0 [m]
    initial_aim: np.ndarray | None  # where the antennas first point; None: the target's first position
    low: np.ndarray
    high: np.ndarray
    antenna: AntennaModel
    displacements: np.ndarray  # (K, 3) Eq. (3), hover first
    pointing: str  # antenna.pointing: "truth" | "aim"
    noise_std: tuple[float, float, float]
    clutter_rate: float
    ospa_cutoff: float
    ospa_order: float
    gate: float  # metrics.gate, track quality judged by the truth [m]
    report_spread: float | None  # fusion.report_spread [m]; None: report whenever e > 0.5
    max_step: float  # max(Delta_R), the clairvoyant chaser's step [m]
    plan: PlanSettings
    team: TeamSettings
    target: TargetParams
    make_filter: Callable[[np.random.Generator], BernoulliFilter]  # one agent's filter from its stream
    cue: tuple[float, float, float] | None  # filter.cue as (e_0, position std [m], velocity std [m/s])
    cue_velocity: bool  # filter.cue.velocity: target (the cue's velocity is the target's first one; else at rest)
    oracle: Oracle | None = None  # oracle: what the team is told of the truth (diagnostic, ours); None: nothing

    def seed_tree(self) -> tuple[np.random.SeedSequence, list[list[np.random.SeedSequence]], np.random.SeedSequence]:
        return seed_tree(self.seed, self.n_agents)


def is_scenario(s: object) -> None:
    """Refuse, naming it, what is not a :class:`Scenario` (a preset's name, a mapping): the
    engines would fail on its first attribute."""
    if not isinstance(s, Scenario):
        raise TypeError(f"scenario: expected a Scenario (trackjam.load_scenario(...)), got {type(s).__name__}")
    unvalidated(s)


def unvalidated(s: Scenario) -> None:
    """Refuse a Scenario that validation would refuse or change: pydantic's
    ``model_copy(update=...)`` sets values unchecked, and a negative ``steps`` had run no step, a
    text failed deep in the engine, a huge particle count went past the memory check. Costs
    about 0.3 ms."""
    import warnings

    with warnings.catch_warnings():  # pydantic warns while it serialises a value of the wrong type
        warnings.simplefilter("ignore")
        data = s.model_dump(round_trip=True)
    again = validate_scenario(data, "scenario")
    if again != s:
        key = next((k for k in type(s).model_fields if getattr(again, k) != getattr(s, k)), "scenario")
        raise ConfigError(f"{key}: the scenario holds a value validation would not give ({getattr(s, key, s)!r:.60}); "
                          "model_copy(update=...) skips validation: use load_scenario(..., key=value)")


def solver_allowed(s: Scenario, solver: str) -> None:
    """Refuse, in one line, a solver that ``s`` with ``control.solver`` set to it would not
    validate: a scenario's solver settings are checked for its own solver only (GRASP's work
    cap, ``control.close_in`` with greedy), and the environment's solver policies switch it. A
    solver registered from a script of one's own, which the configuration does not name, has no
    settings there to check: it is allowed (the README says it drives the environment; it had
    been refused as "Input should be 'greedy', 'grasp' or 'exact'")."""
    if solver not in typing.get_args(type(s.control).model_fields["solver"].annotation):
        return
    data = s.model_dump(round_trip=True)
    data["control"]["solver"] = solver
    try:
        validate_scenario(data, "scenario")
    except ConfigError as err:
        raise ConfigError(f"{solver}: not a solver this scenario takes: {err}") from None


def one_target(s: Scenario) -> None:
    """Refuse a scenario with several targets for the one-target engine, in one line (a run
    with several targets goes through the swarm engine, :func:`build_swarm`)."""
    is_scenario(s)
    if len(s.target_list) > 1:
        raise ConfigError(
            f"targets: {len(s.target_list)} targets given, but this component simulates one target; a run with "
            "several targets goes through the swarm engine (trackjam.simulation.swarm.SwarmSimulation)"
        )


def build(s: Scenario) -> Components:
    c = s.control
    return Components(
        name=s.name,
        steps=s.steps,
        seed=s.seed,
        n_agents=s.n_agents,
        initial_positions=np.asarray(s.agents.initial, dtype=float),
        initial_aim=None if s.agents.initial_aim is None else np.asarray(s.agents.initial_aim, dtype=float),
        low=np.asarray(s.area.low, dtype=float),
        high=np.asarray(s.area.high, dtype=float),
        antenna=antenna_model(s),
        displacements=displacements(s),
        pointing=s.antenna.pointing,
        noise_std=s.sensor.noise_std,
        clutter_rate=float(s.sensor.clutter_rate),
        ospa_cutoff=float(s.metrics.ospa_cutoff),
        ospa_order=float(s.metrics.ospa_order),
        report_spread=None if s.fusion.report_spread is None else float(s.fusion.report_spread), gate=float(s.metrics.gate),
        max_step=float(max(s.agents.radial_steps)),
        plan=PlanSettings(
            solver=c.solver, at_least=c.at_least, constraints=c.constraints, samples=c.grasp.samples,
            iterations=c.grasp.iterations, neighbours=c.grasp.neighbours,
            threads=c.grasp.threads or default_threads(s.n_agents), fallback=c.fallback,
            time_limit_s=c.time_limit_s, node_limit=int(c.node_limit),
            belief_samples=c.belief_samples if c.plan_over == "belief" else 0,
            belief_spread=None if c.belief_spread is None else float(c.belief_spread),
            belief_at_least=None if c.belief_at_least is None else int(c.belief_at_least),
            close_in=None if c.close_in is None else float(c.close_in), greedy_aim=c.greedy_aim,
        ),
        team=TeamSettings(
            existence_rule=s.fusion.existence, feedback=s.fusion.feedback, share=s.fusion.share,
            searching=c.fallback == "search", accel_var=s.filter_accel_var,
            loss=float(s.comms.loss), delay_steps=int(s.comms.delay_steps), stale=s.comms.stale,
            failures=tuple((f.agent, f.step, f.mode) for f in s.comms.failures),
            aim=AimSettings(lead=c.lead, horizon=c.horizon, reach=max(s.agents.radial_steps)),
            search_reseed=s.fusion.search_reseed, last_step=int(s.steps),
        ),
        target=target_params(s),
        make_filter=partial(BernoulliFilter, filter_params(s), antenna_model(s)),
        cue=None if s.filter.cue is None else (s.filter.cue.existence, s.filter.cue.position_std,
                                               s.filter.cue.velocity_std),
        cue_velocity=s.filter.cue is not None and s.filter.cue.velocity == "target",
        oracle=s.oracle,
    )


# The LMB filter's adaptive birth (ours, no key yet): lambda_B, the expected births per scan, and
# r_B^max, the cap on one birth's existence (Reuter et al. 2014, Sec. IV-A)
LMB_BIRTH_RATE = 0.1
LMB_BIRTH_EXISTENCE_MAX = 0.1


# the one-target birth the swarm engine's LMB filters replace with their own adaptive birth
_OWN_BIRTH = ("filter.birth", "filter.birth_prob", "filter.birth_mix")


def _swarm_unsupported(s: Scenario) -> list[tuple[str, object, object]]:
    """Options of the one-target engine the swarm engine does not read yet: (key, its value in
    the scenario, the value the swarm engine runs with); a scenario that sets another is refused."""
    return [
        ("fusion.existence", s.fusion.existence, "mean"),
        ("filter.mode", s.filter.mode, None),
        ("filter.birth", s.filter.birth, "uniform"),  # _OWN_BIRTH: the LMB filters read none of these three
        ("filter.birth_prob", s.filter.birth_prob, 0.02),
        ("filter.birth_mix", s.filter.birth_mix, 0.5),
        ("filter.reserve_memory", s.filter.reserve_memory, 0),
        ("filter.velocity_jitter", s.filter.velocity_jitter, 0.0),
        ("filter.visibility.per_particle", s.filter.visibility is not None and s.filter.visibility.per_particle, False),
        ("filter.team_proposals", s.filter.team_proposals, False),
        ("control.plan_over", s.control.plan_over, "point"),
        ("control.belief_at_least", s.control.belief_at_least, None),
        ("control.close_in", s.control.close_in, None),
        ("control.greedy_aim", s.control.greedy_aim, "team"),
        ("fusion.search_reseed", s.fusion.search_reseed, "always"),
        ("oracle", s.oracle, None),
    ]


@dataclass(frozen=True)
class SwarmComponents:
    """What the swarm engine (several targets) reads beside the one-target components: every
    target's parameters and id, and each agent's LMB filter."""

    base: Components
    targets: list[TargetParams]
    ids: list[int | str]
    lmb: LMBParams
    team_objective: str = "sum"  # control.team_objective: "sum" | "min" of the targets' Xi_k


def lmb_params(s: Scenario) -> LMBParams:
    """Each agent's LMB filter (several targets): the Bernoulli filter's model and particle
    counts per track, its measurement-driven birth speed, the adaptive birth's constants."""
    f = s.filter
    return LMBParams(
        survival_prob=float(f.survival_prob), particles=int(f.particles), birth_particles=int(f.birth_particles),
        birth_rate=LMB_BIRTH_RATE, birth_existence_max=LMB_BIRTH_EXISTENCE_MAX,
        birth_speed=float(f.measurement_birth_speed), accel_var=s.filter_accel_var, walls=f.walls,
        low=np.asarray(s.area.low, dtype=float), high=np.asarray(s.area.high, dtype=float),
        noise_std=np.asarray(s.sensor.noise_std, dtype=float), clutter_rate=float(s.sensor.clutter_rate),
        visibility=None if f.visibility is None else (float(f.visibility.hide), float(f.visibility.reappear)),
        response=fail_safe(s), association_misses=bool(f.association_misses),
    )


def several_targets(s: Scenario) -> bool:
    """The scenario lists more than one target: it runs on the swarm engine."""
    is_scenario(s)
    return len(s.target_list) > 1


def check_swarm_options(s: Scenario, overrides: list[str] | None = None) -> None:
    """Refuse, in one line, an option the swarm engine does not simulate yet, blamed on the
    ``--set`` among ``overrides`` that set it, as a bad value is (`validate`, `run` and the swarm
    experiment check with this before any work; :func:`build_swarm` without ``overrides``)."""
    from trackjam.config.loading import blamed_on_set

    for key, value, runs in _swarm_unsupported(s):
        if value != runs:
            value = [v.model_dump() if hasattr(v, "model_dump") else v for v in value] if isinstance(value, list) \
                else value.model_dump() if hasattr(value, "model_dump") else value
            shown = "null" if runs is None else repr(runs)  # as the scenario file would say it
            how = (f"the swarm engine's LMB filters use their own adaptive birth (leave it at {shown})"
                   if key in _OWN_BIRTH else f"the swarm engine runs with {shown}")
            raise ConfigError(blamed_on_set(f"{key}: {value!r} is not simulated with several targets yet; {how}",
                                            overrides, cause="targets"))


def build_swarm(s: Scenario) -> SwarmComponents:
    """The swarm engine's components; an option it does not simulate yet is refused in one line."""
    is_scenario(s)
    check_swarm_options(s)
    return SwarmComponents(base=build(s), targets=targets_params(s), ids=target_ids(s), lmb=lmb_params(s),
                           team_objective=s.control.team_objective)


def figure_settings(s: Scenario) -> FigureSettings:
    """What the run's figure and replay draw beside the logs."""
    a, m = s.antenna, s.metrics
    return FigureSettings(
        name=s.name, solver=s.control.solver,
        low=np.asarray(s.area.low, dtype=float), high=np.asarray(s.area.high, dtype=float),
        antenna=antenna_model(s), opening_angle_deg=float(a.opening_angle_deg),
        interference_limit_db=float(a.interference_limit_db), power_levels_db=tuple(a.power_levels_db),
        ospa_order=float(m.ospa_order), ospa_cutoff=float(m.ospa_cutoff), gate=float(m.gate),
    )


def scenario_text(s: Scenario) -> str:
    """The resolved scenario as a run's ``scenario.yaml`` holds it."""
    return scenario_to_yaml(s)


def with_seed(s: Scenario, seed: int) -> Scenario:
    """The same scenario on another root seed, in [0, 2^63 - 1] as the scenario's own (a copy
    is not validated again)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= MAX_SEED:
        raise ValueError(f"seed {seed!r}: must be an integer in [0, 2^63 - 1]")
    return s.model_copy(update={"seed": int(seed)})


WARM_STEPS = 2


def warm_up_scenario(s: Scenario) -> Scenario:
    """The scenario's tiny twin (:mod:`trackjam.simulation.warmup`): same agents, solver and
    options, two steps, few particles, and a target present and detectable from the first step
    so the update kernels run too."""
    present = {"appears": 1, "disappears": None, "occlusions": [], "stochastic": None}
    target = s.target.model_copy(update=present)
    targets = None if s.targets is None else [tg.model_copy(update=present) for tg in s.targets]
    return s.model_copy(
        update={
            "steps": WARM_STEPS,
            "target": target,
            "targets": targets,
            "filter": s.filter.model_copy(update={"particles": 40, "birth_particles": 20}),
            "control": s.control.model_copy(update={"grasp": s.control.grasp.model_copy(
                update={"samples": min(s.control.grasp.samples, 20), "iterations": 2})}),
        }
    )
