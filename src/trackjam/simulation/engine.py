"""The step-wise engine: ``Simulation(scenario)``, ``reset()``, ``step(actions=None)``.

One step, in the order of the paper's Fig. 2, each stage one call into the package that owns it:
the truth moves -> each agent predicts and the team exchanges predictions -> the team plans
(or takes the given actions) -> agents move and transmit -> each agent receives its scan and
updates its filter -> the team exchanges and fuses posteriors -> the step is measured.

The diagnostic ``oracle`` section (ours, off by default) tells the team what no real team
knows, at the two points where it could: the true position in place of x_bar when the team
plans, and, after the fusion, the true state (or only the mean) in every filter before an
occlusion; it can also point the antennas at the truth for some steps, or have the filters
weigh an occluded step's scans as if every antenna were off.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from typing import TYPE_CHECKING

import numpy as np

from trackjam.control.planning import position_spread
from trackjam.estimation.fusion import CONFIRM, FusedEstimate
from trackjam.metrics.ospa import ospa
from trackjam.metrics.summary import summarise
from trackjam.radio.antenna import detection_probability, interference_matrix, received_power
from trackjam.radio.measurement import sample_scan
from trackjam.simulation.actions import checked_actions
from trackjam.simulation.agent import Agent
from trackjam.simulation.build import Components, build, one_target
from trackjam.simulation.logs import RunLog
from trackjam.simulation.team import Team
from trackjam.world.target import TruthTarget

if TYPE_CHECKING:  # the scenario is read in one place, simulation/build.py
    from trackjam.simulation.build import Scenario


# oracle.state_before_hiding: the spread of the particles redrawn around the true state
# (0.3 m and 0.1 m/s per axis)
TOLD_COV = np.diag([0.3**2] * 3 + [0.1**2] * 3)


@dataclass(frozen=True)
class Transmission:
    """What the antennas did during a step (Eqs. 9-10)."""

    points: np.ndarray  # (N, 3) where each antenna pointed [m]
    level_w: np.ndarray  # (N,) transmit power [W]
    interference_w: np.ndarray  # (N,) power each agent received from the others [W]
    to_target_w: np.ndarray  # (N,) power each agent put on the target [W]
    p_d: np.ndarray  # (N,) each agent's detection probability of the target


@dataclass(frozen=True)
class StepRecord:
    """One step's record: the rows it adds to the step, agent and measurement logs, and the
    team's fused estimate whether it was reported or not (``step["estimate"]`` is the report;
    None when every agent is down)."""

    t: int
    step: dict
    agents: dict
    scans: list[tuple[np.ndarray, np.ndarray]]
    fused: FusedEstimate | None = None


@dataclass
class RunResult:
    """Everything one run produced: the resolved scenario, the logs as column arrays, and the
    summary figures (:func:`trackjam.metrics.summary.summarise`)."""

    scenario: Scenario
    steps: dict[str, np.ndarray]
    agents: dict[str, np.ndarray]
    measurements: dict[str, np.ndarray]
    summary: dict


def seen(fused: FusedEstimate) -> float:
    """P(a detectable target exists): e_hat, times P(visible) under a hidden-target mode. The
    team reports what it believes it could detect, the set the OSPA and the track quality judge
    (an occluded target counts as absent there)."""
    return fused.existence * (1.0 if fused.visible is None else fused.visible)


def located(cov: np.ndarray, spread: float | None) -> bool:
    """The fused track is tight enough to report: sqrt(trace(C_pos) / 3) <= ``spread`` (always
    when ``spread`` is None)."""
    return spread is None or position_spread(cov) <= spread


class Stepping:
    """A run stepped one step at a time that a step ending half done (an error, a Ctrl-C) leaves
    broken: the truth and the filters had moved on without a log row, so ``step`` and ``result``
    refuse (:meth:`_whole`) until ``reset`` clears ``broken`` (stepping on had given a run with
    a step missing). :class:`Simulation` and the swarm engine's ``SwarmSimulation``."""

    t: int
    broken: str | None = None  # what ended a step half done; reset() clears it

    def _whole(self) -> None:
        if self.broken is not None:
            raise RuntimeError(f"step {self.t} ended half done ({self.broken}): the run cannot go on; call reset()")

    def _guarded(self, step, *args):
        """``step(*args)``, noting in ``broken`` what ended it if it did not return."""
        try:
            return step(*args)
        except BaseException as err:
            self.broken = type(err).__name__ + (f": {str(err).splitlines()[0][:80]}" if str(err) else "")
            raise


class Simulation(Stepping):
    """A scenario run one step at a time. ``step()`` lets the configured solver decide;
    ``step((moves, levels))`` applies the given displacement and level indices, one per agent."""

    def __init__(self, scenario: Scenario) -> None:
        one_target(scenario)
        self.scenario = scenario
        self.c: Components = build(scenario)
        self.reset()

    def reset(self) -> None:
        """Back to t = 0 with fresh random streams from the scenario's seed."""
        c = self.c
        truth_seed, agent_seeds, comms_seed = c.seed_tree()
        self.truth = TruthTarget(c.target, np.random.default_rng(truth_seed))
        first = self.truth.first_state
        aim = c.initial_aim if c.initial_aim is not None else first[:3]
        velocity = first[3:6] if c.cue_velocity else None
        agents = [
            Agent.create(j, u, aim, c.make_filter(np.random.default_rng(filter_seed)), c.cue, sensor_seed, plan_seed,
                         velocity)
            for j, (u, (filter_seed, sensor_seed, plan_seed)) in enumerate(zip(c.initial_positions, agent_seeds))
        ]
        self.team = Team(agents, c.team, np.random.default_rng(comms_seed))
        self.log = RunLog(n_agents=len(agents), gate=c.gate)
        self.t = 0
        self.follow = 0  # oracle.follow_up: steps left on which the team is told the truth
        self.broken = None

    @property
    def done(self) -> bool:
        return self.t >= self.c.steps

    def step(self, actions: tuple[np.ndarray, np.ndarray] | None = None) -> StepRecord:
        """One step (Algorithm 1); ``actions`` (moves, levels) replace the team's decisions. A step
        that ends half done leaves the run broken until ``reset`` (:class:`Stepping`)."""
        self._whole()
        if self.done:
            raise RuntimeError(f"the run has ended (step {self.t} of {self.c.steps}); call reset()")
        c, team = self.c, self.team
        if actions is not None:  # refused before the step changes anything
            actions = checked_actions(actions, team.positions, c.displacements, len(c.antenna.levels_w), c.low, c.high)
        return self._guarded(self._step, actions)

    def _step(self, actions) -> StepRecord:
        c, team, truth = self.c, self.team, self.truth
        t0 = time.perf_counter()
        self.t = t = self.t + 1
        truth.step(t)
        team.predict(t, c.plan.belief_samples)
        decisions, solve_s = team.decide(c.displacements, c.antenna, c.low, c.high, c.plan, actions, self._told(t))
        prev = team.positions
        team.apply(decisions, c.displacements)
        levels = np.array([d.level for d in decisions], dtype=np.int64)
        tx = self._transmit(levels)
        truth.apply_jamming(t, float(tx.to_target_w.sum()))
        scans = self._scans(tx)
        oracle = c.oracle
        weighed_w = tx.level_w
        if oracle is not None and oracle.empty_hidden_scans and truth.exists and not truth.detectable:  # occluded
            weighed_w = np.zeros_like(tx.level_w)
        posteriors = team.update([Z for Z, _ in scans], tx.points, weighed_w)
        fused = team.fuse(posteriors)
        team.note_jamming(tx.points, tx.level_w)
        if oracle is not None:
            self._tell_after_update(t, [bool(f.any()) for _, f in scans])
        report = next((d for d in decisions if d.mode != "down"), decisions[0])
        existence = np.nan if fused is None else fused.existence
        est = fused.mean[:3] if (fused is not None and fused.mean is not None and seen(fused) > CONFIRM
                                 and located(fused.cov, c.report_spread)) else None
        truth_set = truth.position if truth.detectable else None
        err = ospa(truth_set, est, c=c.ospa_cutoff, p=c.ospa_order)
        record = StepRecord(
            t=t,
            step=dict(
                t=t, target_exists=truth.exists, target_detectable=truth.detectable,
                truth=truth.position, existence=existence, estimate=est, ospa=err, aim=report.x_bar,
                mode=report.mode, objective=report.objective, optimal=report.optimal, gap=report.gap,
                closed_in=report.closed_in,
                target_received_w=float(tx.to_target_w.sum()), solve_s=solve_s, step_s=time.perf_counter() - t0,
            ),
            agents=dict(
                t=t, prev=prev, pos=team.positions, level_index=levels, power_w=tx.level_w,
                point=tx.points, p_d=tx.p_d, detected=np.array([bool(f.any()) for _, f in scans]),
                n_measurements=np.array([len(Z) for Z, _ in scans]),
                existence=np.array([np.nan if m is None else m.estimate.existence for m in posteriors]),
                interference_w=tx.interference_w, jammed=tx.interference_w >= c.antenna.delta_w,
                to_target_w=tx.to_target_w, mode=np.array([d.mode for d in decisions]),
                heard=np.array([d.heard for d in decisions], dtype=np.int64),
            ),
            scans=scans,
            fused=fused,
        )
        self.log.add(record)
        return record

    def _told(self, t: int) -> np.ndarray | None:
        """``oracle`` (diagnostic, ours): the target's true position when the team is told it at
        step ``t`` (on the first ``truth_after_hiding`` steps after an occlusion, or while a
        ``follow_up`` runs), else None."""
        oracle, truth = self.c.oracle, self.truth
        if oracle is None:
            return None
        following = self.follow > 0  # a follow-up's steps run out whether or not the target is there
        self.follow = max(self.follow - 1, 0)
        after = self._just_after_hiding(t, oracle.truth_after_hiding)
        return truth.position.copy() if truth.exists and (after or following) else None

    def _just_after_hiding(self, t: int, k: int) -> bool:
        """Step ``t`` is one of the first ``k`` steps after an occlusion ends."""
        return any(b < t <= b + k for _, b in self.c.target.occlusions)

    def _tell_after_update(self, t: int, detected: list[bool]) -> None:
        """``oracle``, after the step's fusion: a detection after an occlusion starts a follow-up
        (``follow_up``), and before an occlusion every working agent's particles are redrawn
        tight around the true state (``state_before_hiding``) or moved so that their mean is
        the true state (``mean_before_hiding``), each filter keeping its existence."""
        oracle, truth, occlusions = self.c.oracle, self.truth, self.c.target.occlusions
        if oracle.follow_up and truth.detectable and any(detected) and any(b < t for _, b in occlusions):
            self.follow = oracle.follow_up
        told_state = oracle.state_before_hiding or oracle.mean_before_hiding
        if told_state and truth.exists and any(a == t + 1 for a, _ in occlusions):
            for j in self.team.working():
                f = self.team.agents[j].filter
                if oracle.state_before_hiding:
                    f.reset_to(f.e, truth.state.copy(), TOLD_COV)
                elif oracle.mean_before_hiding:
                    f.shift_to(truth.state)

    def _transmit(self, levels: np.ndarray) -> Transmission:
        """Antennas point at the true target (`pointing: truth`, the paper) or at the aim, and
        transmit the decided levels; occlusion hides the target from detection, while the
        jamming power still reaches it."""
        c, truth, team = self.c, self.truth, self.team
        n = len(team.agents)
        x_true = truth.position
        positions = team.positions
        told = c.oracle is not None and self._just_after_hiding(self.t, c.oracle.point_after_hiding)
        if (c.pointing == "truth" or told) and x_true is not None:
            points = np.repeat(x_true[None, :], n, axis=0)
        else:
            points = team.aims
        level_w = c.antenna.levels_w[levels]
        interference = interference_matrix(positions, points, level_w, c.antenna).sum(axis=1)
        p_d, to_target = np.zeros(n), np.zeros(n)
        if truth.exists:
            to_target = received_power(x_true, positions, points, level_w, c.antenna)
            if truth.detectable:
                p_d = detection_probability(x_true, positions, points, level_w, c.antenna)
        return Transmission(points, level_w, interference, to_target, p_d)

    def _scans(self, tx: Transmission) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each working agent's scan (Eqs. 6-8): a detection with probability p_D, plus clutter;
        an agent that broke down receives nothing."""
        c, truth = self.c, self.truth
        target = truth.position if truth.detectable else None
        working = set(self.team.working())
        return [
            sample_scan(a.sensor_rng, target, a.position, float(tx.p_d[j]), c.noise_std, c.clutter_rate,
                        c.antenna.max_range)
            if j in working else (np.zeros((0, 3)), np.zeros(0, dtype=bool))
            for j, a in enumerate(self.team.agents)
        ]

    def result(self) -> RunResult:
        """The logs so far, as column arrays, and their summary."""
        self._whole()
        if not self.log.steps:  # no step logged (none run, or the first interrupted): a KeyError from the summary
            raise RuntimeError("result() before the first step: call step() first")
        c = self.c
        steps, agents, meas = self.log.columns()
        summary = summarise(steps, agents, name=c.name, seed=c.seed, n_agents=c.n_agents,
                            solver=c.plan.solver, downed_at=self.truth.downed_at, gate=c.gate,
                            initial=c.initial_positions, max_step=c.max_step, low=c.low, high=c.high)
        return RunResult(self.scenario, steps, agents, meas, summary)
