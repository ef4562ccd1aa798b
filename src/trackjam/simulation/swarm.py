"""The swarm engine (ours, issue 12): a run with several targets, one step at a time.

``SwarmSimulation(scenario)``, ``reset()``, ``step()`` as :class:`trackjam.simulation.engine.
Simulation`, a thin loop over the several-target blocks. One step:

1. the truth swarm moves (:class:`trackjam.world.swarm.TruthSwarm`);
2. every agent predicts its LMB filter (:class:`trackjam.estimation.lmb.LMBFilter`); the
   predicted tracks are fused across agents (:func:`trackjam.estimation.lmb_fusion.fuse_tracks`)
   and the confirmed ones (fused existence > 0.5), most likely first, then with
   ``control.fallback: search`` the lost tracks coasted (:mod:`trackjam.simulation.swarm_search`),
   at most ``MAX_AIMS`` in all, give the planning aims x_bar_k (moved ahead by ``control.lead`` /
   ``control.horizon``);
3. :func:`trackjam.control.assignment.solve_assignment` picks each agent's (move, level, aim);
   with no aim the team hovers at its last aims with the fall-back levels
   (:func:`trackjam.control.fallback.fallback_levels`); ``step((moves, levels, serves))`` applies
   the given ones instead (:meth:`SwarmSimulation._given`: each agent serves the predicted team
   track holding the track it names, or keeps its last aim when that track is gone);
4. antennas point at the aim they serve (``antenna.pointing: aim``) or, under ``truth``, at the
   true position of the target matched to that aim within ``metrics.gate`` (the aim when none
   is); :func:`trackjam.radio.measurement.target_exposure` gives each target's power and p_D;
5. every agent scans (:func:`trackjam.radio.measurement.sample_scan_multi`) and updates its
   filter; the tracks are fused across agents, each cluster from the members whose cone reached
   it when some did (:func:`informed_fusion`), and, with ``fusion.feedback``, every track of a
   cluster of two or more agents takes the fused existence and is redrawn from the fused
   Gaussian when there is one (a track only one agent holds is left as it is: fusion changed
   nothing, and redrawing the many short-lived clutter births would cost most of the step);
   with ``fusion.share: scans`` every agent also updates on every teammate's scan of the step
   (the LMB's iterated corrector), every member of a cluster is informed, and there is no
   feedback (each filter already holds every scan);
6. the confirmed tracks (with ``fusion.report_spread``, those whose fused position spread is at
   most that; with ``filter.visibility``, those with existence x P(visible) > 0.5) are reported
   and judged against the detectable targets (:mod:`trackjam.metrics.multi`); with ``control.fallback: search`` the team remembers the confirmed ones' states.

With every message delivered, every agent holds the same tracks and the team acts as one: one
fusion and one solve a step serve every agent (:meth:`SwarmSimulation._step`).

Faults (``comms``, ours, as the one-target team's in :mod:`trackjam.simulation.team`;
:meth:`SwarmSimulation._step_team`): the predicted tracks, the scans (``fusion.share: scans``)
and the updated tracks pass through the team's :class:`~trackjam.simulation.team.Exchange` (a
message to another agent is lost with probability ``loss``, drawn from the run's comms stream,
and arrives ``delay_steps`` late; ``failures`` stop an agent's publisher, its channel, or the
agent). Each working agent fuses its own predicted tracks with those of this step that reached
it (a late prediction only tells where its sender was), takes its aims from that view and its
own memory of the lost tracks, and plans with the solver over the agents it heard from, every
other teammate guarded at its last known position (a receiver of Eq. (13) that adds to no
Xi_k); it applies its own move, level and served aim. Agents holding the same problem solve it
once. Each working agent updates on its scan (and the teammates' of this step that reached it;
under ``comms.stale: coast`` also the late ones, weighed at the particles retrodicted to their
step), then fuses its updated tracks with the teammates' that reached it, the late ones
predicted by Eq. (1) to now under ``coast`` and ignored under ``drop``; the feedback resets its
own filter's tracks only. The team's report, metrics and step row are the lowest-index working
agent's, as the one-target engine's (no track once every agent is down). A broken agent
(``breakdown``) hovers with its antenna off, senses, sends and hears nothing; its mode is
``down``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from trackjam.control.assignment import AssignmentProblem, SolverOptions, build_assignment, solve_assignment
from trackjam.control.fallback import fallback_levels
from trackjam.errors import bounded_repr
from trackjam.estimation.bernoulli import Estimate, Scan
from trackjam.estimation.fusion import CONFIRM, fuse_unchecked
from trackjam.estimation.lmb import LMBFilter, Track, TrackEstimate
from trackjam.estimation.lmb_fusion import FusedTrack, fuse_tracks_unchecked
from trackjam.metrics.multi import gated_assignment, ospa_parts
from trackjam.radio.antenna import detection_probability, interference_matrix
from trackjam.radio.measurement import sample_scan_multi, target_exposure_unchecked
from trackjam.simulation.actions import checked_actions
from trackjam.simulation.agent import Message
from trackjam.simulation.build import SwarmComponents, build_swarm
from trackjam.simulation.engine import Stepping, located
from trackjam.simulation.swarm_logs import SwarmLog, swarm_summary
from trackjam.simulation.swarm_search import Aim, SearchMemory, plan_point
from trackjam.simulation.team import Exchange, latest_by_sender
from trackjam.world.motion import cv_coast
from trackjam.world.swarm import TruthSwarm

if TYPE_CHECKING:  # the scenario is read in one place, simulation/build.py
    from trackjam.simulation.build import Scenario

MAX_AIMS = 4  # the team plans at its most likely confirmed tracks, at most this many (ours)


@dataclass
class SwarmAgent:
    """One pursuer of the swarm run: position, aim, the track it serves, filter and streams."""

    index: int
    position: np.ndarray
    aim: np.ndarray
    filter: LMBFilter
    sensor_rng: np.random.Generator
    plan_rng: np.random.Generator
    serves: str = ""  # label of the track its cone serves (or searches for); "" while hovering
    mode: str = "hover"  # "track" | "search" (its aim is a lost track) | "hover"


@dataclass(frozen=True)
class SwarmRecord:
    """One step's rows of the swarm logs (:mod:`trackjam.simulation.swarm_logs`)."""

    t: int
    step: dict
    targets: dict
    tracks: dict
    agents: dict
    scans: list[tuple[np.ndarray, np.ndarray]]
    p_d: np.ndarray | None = None  # (N, K) each agent's p_D of each true target (0 absent or occluded); not logged


@dataclass
class SwarmResult:
    """A swarm run: the scenario, its five logs as column arrays (``tables``: steps, targets,
    tracks, agents, measurements) and the summary."""

    scenario: Scenario
    tables: dict[str, dict[str, np.ndarray]]
    summary: dict

    @property
    def steps(self) -> dict[str, np.ndarray]:
        return self.tables["steps"]

    @property
    def agents(self) -> dict[str, np.ndarray]:
        return self.tables["agents"]

    @property
    def measurements(self) -> dict[str, np.ndarray]:
        return self.tables["measurements"]


def cue_tracks(lmb: LMBFilter, first: np.ndarray, present: list[bool],
               cue: tuple[float, float, float], velocities: np.ndarray | None = None) -> list[Track]:
    """``filter.cue`` for several targets (ours): the team is briefed, as the one-target engine
    is, on where each target present from step 1 is first seen; every agent's filter starts with
    one track per such target, labelled (0, k), existence e_0, particles from a Gaussian around
    its first position (position std, velocity std as ``cue``), at rest, or, given
    ``velocities`` (K, 3) (``filter.cue.velocity: target``), around [x - v_k, v_k], which Eq. (1)
    predicts to x at step 1."""
    existence, pos_std, vel_std = cue
    n = lmb.p.particles
    tracks = []
    for k, (x, here) in enumerate(zip(first, present)):
        if not here or not np.all(np.isfinite(x)):
            continue
        v = np.zeros(3) if velocities is None else velocities[k]
        X = np.concatenate([x - v, v]) + lmb.rng.standard_normal((n, 6)) * np.array([pos_std] * 3 + [vel_std] * 3)
        tracks.append(Track((0, k), float(existence), X, np.full(n, -np.log(n))))
    return tracks


def member_indices(track: FusedTrack, own: list[list[TrackEstimate]]) -> list[tuple[int, int]]:
    """(agent, index in ``own[agent]``) of each member track of a fused track."""
    return [(a, next(i for i, e in enumerate(own[a]) if e.label == label)) for a, label in track.members]


def informed_fusion(team: list[FusedTrack], own: list[list[TrackEstimate]],
                    informed: list[np.ndarray]) -> list[FusedTrack]:
    """Each cluster's estimate from its informed members only, when it has some and not all of
    its members are (ours): a member whose cone did not reach the track this step (p_D = 0 at its
    mean) holds a prediction, not news, and would pull the fused state back to it; with every
    member informed (one target, every cone on it) this is the fusion of the whole cluster."""
    out = []
    for f in team:
        index = member_indices(f, own)
        told = [(a, i) for a, i in index if informed[a][i]]
        if told and len(told) < len(index):
            est = fuse_unchecked([Estimate(own[a][i].existence, own[a][i].mean, own[a][i].cov) for a, i in told])
            f = FusedTrack(f.members, est)
        out.append(f)
    return out


def coasted_tracks(late: list[Message], t: int, accel_var: float) -> list[Message]:
    """``comms.stale: coast`` with several targets (ours, as
    :func:`~trackjam.simulation.team.coasted_posteriors`): of the late posteriors that arrived,
    each sender's latest only, every track's mean and covariance predicted by Eq. (1) from its
    step to ``t`` (existence, visibility and label as sent)."""
    out = []
    for m in latest_by_sender(late):
        tracks = [replace(e, mean=mean, cov=cov) for e in m.tracks
                  for mean, cov in [cv_coast(e.mean, e.cov, accel_var, t - m.stamp)]]
        out.append(replace(m, tracks=tracks))
    return out


def guarded_assignment(problem: AssignmentProblem, n_planned: int) -> AssignmentProblem:
    """The problem with its agents from ``n_planned`` on held at hover and adding nothing to any
    target's Xi_k (p_D = 0), still receivers of Eq. (13): teammates an agent did not hear from
    this step (:meth:`trackjam.control.problem.Problem.guarded` per aim)."""
    pz = problem.pz.copy()
    pz[:, n_planned:, :] = 0.0
    return replace(problem, targets=tuple(P.guarded(n_planned) for P in problem.targets), pz=pz)


def track_label(track: FusedTrack) -> str:
    """The team's label of a fused track: its oldest member's, ``aA:B.I`` (agent A's track born
    at step B as birth I), so the label stays while that track lives whoever else joins."""
    agent, (born, i) = min(track.members, key=lambda m: (m[1][0], m[0], m[1][1]))
    return f"a{agent}:{born}.{i}"


def visible(track: FusedTrack, own: list[list[TrackEstimate]]) -> float:
    """P(visible | exists) of a fused track under the hidden-target mode (``filter.visibility``):
    the mean over its members' (1 without the mode). As the one-target engine does, the team
    reports a track only while existence x P(visible) > 0.5, what it believes it could detect
    (an occluded target counts as absent in the OSPA and the track quality); it keeps planning
    at one it believes hidden."""
    nus = [own[a][i].visible for a, i in member_indices(track, own)]
    return float(np.mean(nus)) if nus else 1.0


def confirmed(tracks: list[FusedTrack]) -> list[FusedTrack]:
    """The fused tracks the team believes in (existence > 0.5, with a fused state), most likely
    first (ties by label)."""
    sure = [f for f in tracks if f.estimate.existence > CONFIRM and f.estimate.mean is not None]
    return sorted(sure, key=lambda f: (-f.estimate.existence, track_label(f)))


def checked_swarm_actions(actions, positions: np.ndarray, displacements: np.ndarray, n_levels: int,
                          low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """``(moves, levels, serves)`` as two int64 arrays and a list of texts, one per agent, or a
    ValueError naming the argument: the moves and levels as the one-target engine checks them
    (:func:`~trackjam.simulation.actions.checked_actions`), each served label a text."""
    n = len(positions)
    if not isinstance(actions, (tuple, list)) or len(actions) != 3:
        raise ValueError(f"actions: expected a triple (moves, levels, serves) of {n} entries each, "
                         f"got {bounded_repr(actions, 60)}")
    moves, levels = checked_actions(actions[:2], positions, displacements, n_levels, low, high)
    serves = actions[2]
    if (isinstance(serves, (str, bytes)) or not isinstance(serves, (tuple, list, np.ndarray)) or len(serves) != n
            or not all(isinstance(s, str) for s in serves)):
        raise ValueError(f"actions: serves must be {n} track labels (texts, \"\" for none), got {bounded_repr(serves, 60)}")
    return moves, levels, [str(s) for s in serves]


class SwarmSimulation(Stepping):
    """A scenario with several targets run one step at a time; ``step()`` lets the configured
    solver decide the moves, levels and served aims, ``step((moves, levels, serves))`` applies
    the given displacement and level indices and served track labels, one per agent."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.c: SwarmComponents = build_swarm(scenario)
        team = self.c.base.team
        # each agent on its own view (the comms faults); False: the team acts as one, one solve a step
        self.distributed = team.loss > 0 or team.delay_steps > 0 or bool(team.failures)
        self.reset()

    def reset(self) -> None:
        """Back to t = 0 with fresh random streams from the scenario's seed."""
        c, b = self.c, self.c.base
        truth_seed, agent_seeds, comms_seed = b.seed_tree()
        self.truth = TruthSwarm.from_seed(c.targets, c.ids, truth_seed)
        first = self.truth.first_positions
        velocities = self.truth.first_velocities if b.cue_velocity else None
        centre = (b.low + b.high) / 2
        self.agents = []
        for j, (u, (filter_seed, sensor_seed, plan_seed)) in enumerate(zip(b.initial_positions, agent_seeds)):
            # agent j first points at target j mod K (where it will appear), or at initial_aim
            aim = b.initial_aim if b.initial_aim is not None else first[j % len(first)]
            aim = centre if not np.all(np.isfinite(aim)) else aim
            lmb = LMBFilter(c.lmb, b.antenna, np.random.default_rng(filter_seed))
            if b.cue is not None:
                lmb.tracks = cue_tracks(lmb, first, [p.appears <= 1 and p.stochastic is None for p in c.targets], b.cue,
                                        velocities)
            self.agents.append(SwarmAgent(j, np.array(u, dtype=float), np.array(aim, dtype=float), lmb,
                                          np.random.default_rng(sensor_seed), np.random.default_rng(plan_seed)))
        self.memory = SearchMemory(b.team.accel_var) if b.team.searching else None
        n = len(self.agents)
        # the comms faults: every agent fuses, remembers and plans from what reached it
        # (:meth:`_step_team`); without them every agent's view is the team's and one solve serves all
        self.exchange = Exchange(n, b.team, np.random.default_rng(comms_seed))
        briefing = {a.index: (0, a.position.copy()) for a in self.agents}  # where the team starts
        self.known = [dict(briefing) for _ in range(n)]  # teammate -> (stamp, position) last heard
        self.memories = [SearchMemory(b.team.accel_var) for _ in range(n)] if b.team.searching else None
        # each agent's fused view of the last step: its predicted tracks and its updated ones
        self.predicted_views: list[list[FusedTrack]] = [[] for _ in range(n)]
        self.views: list[list[FusedTrack]] = [[] for _ in range(n)]
        self.log = SwarmLog([str(i) for i in c.ids])
        self.t = 0
        self.broken = None
        # the team's confirmed tracks now (the cue's before the first step), what a controller may serve
        self.sure = confirmed(fuse_tracks_unchecked([a.filter.estimates() for a in self.agents]))

    @property
    def done(self) -> bool:
        return self.t >= self.c.base.steps

    @property
    def positions(self) -> np.ndarray:
        return np.array([a.position for a in self.agents])

    def step(self, actions: tuple | None = None) -> SwarmRecord:
        """One step; ``actions`` (moves, levels, serves) replace the team's decisions: a
        displacement index, a level index and the label of the team track served (``""``: none,
        the antenna keeps its last aim) per agent. One that ends half done leaves the run broken
        until ``reset`` (:class:`~trackjam.simulation.engine.Stepping`)."""
        self._whole()
        b = self.c.base
        if self.done:
            raise RuntimeError(f"the run has ended (step {self.t} of {b.steps}); call reset()")
        if actions is not None:  # refused before the step changes anything
            actions = checked_swarm_actions(actions, self.positions, b.displacements, len(b.antenna.levels_w),
                                            b.low, b.high)
        return self._guarded(self._step_team if self.distributed else self._step, actions)

    def _step(self, actions: tuple | None = None) -> SwarmRecord:
        b = self.c.base
        t0 = time.perf_counter()
        self.t = t = self.t + 1
        truth = self.truth
        truth.step(t)
        predicted = fuse_tracks_unchecked([a.filter.predict() for a in self.agents])
        if actions is None:
            aims = self._aims(t, predicted)
            t_plan = time.perf_counter()
            plan = self._plan(aims)
        else:
            t_plan = time.perf_counter()
            aims, plan = self._given(predicted, *actions)
        solve_s = time.perf_counter() - t_plan
        prev = self.positions
        for a, move, k in zip(self.agents, plan["move"], plan["serve"]):
            a.position = a.position + b.displacements[move]
            if k >= 0:
                a.aim, a.serves, a.mode = aims[k].point.copy(), aims[k].label, "search" if aims[k].search else "track"
            else:
                a.serves, a.mode = "", "hover"
        positions = self.positions
        points = self._points(aims, plan["serve"])
        level_w = b.antenna.levels_w[plan["level"]]
        to_target, p_d = target_exposure_unchecked(np.nan_to_num(truth.positions), truth.exists, truth.detectable,
                                                   positions, points, level_w, b.antenna)
        received = to_target.sum(axis=0)
        truth.apply_jamming(t, received)
        X = truth.detectable_positions
        scans = [sample_scan_multi(a.sensor_rng, X, a.position, p_d[j], b.noise_std, b.clutter_rate,
                                   b.antenna.max_range) for j, a in enumerate(self.agents)]
        shared = b.team.share == "scans"
        sent = [Scan.of(Z, a.position, points[j], float(level_w[j]), b.antenna) if shared else None
                for j, (a, (Z, _)) in enumerate(zip(self.agents, scans))]
        own = [a.filter.update(Z, a.position, points[j], float(level_w[j]),
                               [sc for k, sc in enumerate(sent) if k != j] if shared else ())
               for j, (a, (Z, _)) in enumerate(zip(self.agents, scans))]
        # with every scan in every filter each agent is informed of every track it holds
        informed = [np.ones(len(m), dtype=bool) for m in own] if shared else self._informed(own, points, level_w)
        team = informed_fusion(fuse_tracks_unchecked(own), own, informed)
        if b.team.feedback and not shared:
            self._feed_back(team)
        for a in self.agents:  # filter.response: each filter knows the team's transmissions of the step
            a.filter.note_jamming(positions, points, level_w)
        self.predicted_views, self.views = [predicted] * len(self.agents), [team] * len(self.agents)
        sure = self.sure = confirmed(team)
        if self.memory is not None:
            self.memory.remember(t, [(track_label(f), f.estimate.mean, f.estimate.cov) for f in sure])
        n = len(self.agents)
        return self._record(t, t0, solve_s, prev, len(aims), plan, points, level_w, to_target, received, p_d, scans,
                            own, sure, plan["mode"], [a.mode for a in self.agents], np.full(n, n, dtype=np.int64))

    def _step_team(self, actions: tuple | None = None) -> SwarmRecord:
        """One step under the ``comms`` faults (the module docstring, "Faults"): predictions,
        scans (``fusion.share: scans``) and posteriors pass through the team's exchange, and
        every working agent fuses, remembers and plans from what reached it."""
        b, c = self.c.base, self.c
        t0 = time.perf_counter()
        self.t = t = self.t + 1
        truth, ex, n = self.truth, self.exchange, len(self.agents)
        truth.step(t)
        working = [j for j in range(n) if not ex.down(j, t)]
        # round 1: each working agent predicts and announces its position, aim and predicted tracks
        sent = [Message(j, "prediction", t, position=self.agents[j].position.copy(), aim=self.agents[j].aim.copy(),
                        tracks=self.agents[j].filter.predict()) for j in working]
        inboxes = ex.send(t, "prediction", sent)
        fresh: list[list[Message]] = [[] for _ in range(n)]
        for j in working:
            for m in inboxes[j]:  # a late prediction tells where the teammate was, nothing more
                if self.known[j][m.sender][0] <= m.stamp:
                    self.known[j][m.sender] = (m.stamp, m.position)
            fresh[j] = [m for m in inboxes[j] if m.stamp == t]
        predicted: list[list[FusedTrack]] = [[] for _ in range(n)]
        views: dict[tuple[int, ...], list[FusedTrack]] = {}  # agents that heard the same agents fuse alike
        for j in working:
            key = tuple(m.sender for m in fresh[j])
            if key not in views:
                views[key] = fuse_tracks_unchecked(self._by_agent(fresh[j], n))
            predicted[j] = views[key]
        t_plan = time.perf_counter()
        if actions is None:
            aims = {j: self._aims(t, predicted[j], np.array([m.position for m in fresh[j]]),
                                  None if self.memories is None else self.memories[j]) for j in working}
            plans = self._plans(working, fresh, aims)
        else:
            aims, plans = {}, {}
            for j in working:
                aims[j], plan = self._given(predicted[j], *actions, positions=np.array([m.position for m in fresh[j]]))
                plans[j] = dict(plan, row=j)
        solve_s = time.perf_counter() - t_plan
        prev = self.positions
        serve = np.full(n, -1)
        moves, levels = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)  # a broken agent hovers, off
        for j in working:
            plan, i = plans[j], plans[j]["row"]
            moves[j], levels[j], serve[j] = plan["move"][i], plan["level"][i], plan["serve"][i]
        for j, a in enumerate(self.agents):
            a.position = a.position + b.displacements[moves[j]]
            k = serve[j]
            if k >= 0:
                aim = aims[j][k]
                a.aim, a.serves, a.mode = aim.point.copy(), aim.label, "search" if aim.search else "track"
            else:
                a.serves, a.mode = "", "hover" if j in working else "down"
        positions = self.positions
        points = self._points_each(aims, serve)
        level_w = b.antenna.levels_w[levels]
        to_target, p_d = target_exposure_unchecked(np.nan_to_num(truth.positions), truth.exists, truth.detectable,
                                                   positions, points, level_w, b.antenna)
        received = to_target.sum(axis=0)
        truth.apply_jamming(t, received)
        X = truth.detectable_positions
        nothing = (np.zeros((0, 3)), np.zeros(0, dtype=np.int64))  # a broken agent senses nothing
        scans = [sample_scan_multi(a.sensor_rng, X, a.position, p_d[j], b.noise_std, b.clutter_rate,
                                   b.antenna.max_range) if j in working else nothing
                 for j, a in enumerate(self.agents)]
        shared = b.team.share == "scans"
        others: dict[int, list[Scan]] = {j: [] for j in working}
        if shared:  # each agent's scan to the others, under the faults; a late one weighs under coast
            boxes = ex.send(t, "scan", [Message(j, "scan", t, scan=Scan.of(scans[j][0], self.agents[j].position,
                                                                             points[j], float(level_w[j]), b.antenna))
                                        for j in working])
            coast = b.team.stale == "coast"
            others = {j: [m.scan if m.stamp == t else m.scan.late(t - m.stamp) for m in boxes[j]
                          if m.sender != j and (m.stamp == t or coast)] for j in working}
        own: list[list[TrackEstimate]] = [[] for _ in range(n)]
        for j in working:
            a = self.agents[j]
            own[j] = a.filter.update(scans[j][0], a.position, points[j], float(level_w[j]), others[j])
        informed = [np.ones(len(m), dtype=bool) for m in own] if shared else self._informed(own, points, level_w)
        # round 3: each working agent announces its tracks and fuses the ones that reached it
        boxes = ex.send(t, "posterior", [Message(j, "posterior", t, position=self.agents[j].position.copy(),
                                                 tracks=own[j], informed=informed[j]) for j in working])
        team: list[list[FusedTrack]] = [[] for _ in range(n)]
        held: list[list[list[TrackEstimate]]] = [[[] for _ in range(n)] for _ in range(n)]
        fused: dict[tuple[int, ...], tuple] = {}
        for j in working:
            box = [m for m in boxes[j] if m.stamp == t]
            if b.team.stale == "coast":
                box = coasted_tracks([m for m in boxes[j] if m.stamp < t], t, c.lmb.accel_var) + box
            key = tuple(id(m) for m in box)
            if key not in fused:
                tracks, flags = self._by_agent(box, n), [np.zeros(0, dtype=bool) for _ in range(n)]
                for m in box:
                    flags[m.sender] = m.informed
                fused[key] = (informed_fusion(fuse_tracks_unchecked(tracks), tracks, flags), tracks)
            team[j], held[j] = fused[key]
        if b.team.feedback and not shared:
            for j in working:
                self._feed_back(team[j], only=j)
        for j in working:  # filter.response: each filter knows the team's transmissions of the step
            self.agents[j].filter.note_jamming(positions, points, level_w)
        self.predicted_views, self.views = predicted, team
        sure_of = {j: confirmed(team[j]) for j in working}
        if self.memories is not None:
            for j in working:
                self.memories[j].remember(t, [(track_label(f), f.estimate.mean, f.estimate.cov) for f in sure_of[j]])
        # the team's report: the lowest-index working agent's view, as the one-target team's
        r = working[0] if working else None
        sure = self.sure = [] if r is None else sure_of[r]
        plan = plans[r] if r is not None else dict(mode="down", objective=np.nan, optimal=False, gap=np.nan)
        heard = np.array([len(fresh[j]) for j in range(n)], dtype=np.int64)
        return self._record(t, t0, solve_s, prev, 0 if r is None else len(aims[r]), dict(plan, level=levels), points,
                            level_w, to_target, received, p_d, scans, [] if r is None else held[r], sure,
                            plan["mode"], [a.mode for a in self.agents], heard, own)

    @staticmethod
    def _by_agent(messages: list[Message], n: int) -> list[list[TrackEstimate]]:
        """The tracks of ``messages`` at their senders' indices (none for an agent not heard):
        the fused tracks' members keep the agents' own indices."""
        tracks: list[list[TrackEstimate]] = [[] for _ in range(n)]
        for m in messages:
            tracks[m.sender] = m.tracks
        return tracks

    def _plans(self, working: list[int], fresh: list[list[Message]], aims: dict[int, list[Aim]]) -> dict[int, dict]:
        """Each working agent's plan from its view: the solver over the agents it heard from this
        step (its rows; ``row`` is its own), every other teammate guarded at its last known
        position (a receiver of Eq. (13) that adds nothing to the objective, as the one-target
        team's). Agents holding the same problem solve it once (with none of the faults, every
        agent: the team's one solve); under ``grasp``, a row that is not one of them searches
        with a stream spawned from the first one's."""
        b, p = self.c.base, self.c.base.plan
        groups: dict[tuple, list[int]] = {}
        for j in working:
            rows = tuple(m.sender for m in fresh[j])
            guards = tuple(sorted(k for k in self.known[j] if k not in rows))
            key = (rows, guards, tuple(m.position.tobytes() for m in fresh[j]),
                   tuple(self.known[j][k][1].tobytes() for k in guards),
                   tuple((a.label, a.point.tobytes(), a.search) for a in aims[j]),
                   () if aims[j] else tuple(m.aim.tobytes() for m in fresh[j]))
            groups.setdefault(key, []).append(j)
        out = {}
        for (rows, guards, *_), members in groups.items():
            j0 = members[0]
            heard = fresh[j0]
            positions = np.array([m.position for m in heard] + [self.known[j0][k][1] for k in guards])
            if not aims[j0]:
                levels = fallback_levels(positions[:len(rows)], np.array([m.aim for m in heard]), b.antenna,
                                         p.constraints)
                plan = dict(mode="hover", move=np.zeros(len(rows), dtype=np.int64),
                            level=np.asarray(levels, dtype=np.int64), serve=np.full(len(rows), -1),
                            objective=np.nan, optimal=False, gap=np.nan)
            else:
                x_bar = np.array([a.point for a in aims[j0]])
                problem = build_assignment(positions, x_bar, b.displacements, b.antenna, b.low, b.high,
                                           min(p.at_least, len(rows)), p.constraints, self.c.team_objective)
                if guards:
                    problem = guarded_assignment(problem, len(rows))
                spare = self.agents[j0].plan_rng
                rngs = [self.agents[k].plan_rng if k in members else
                        (spare.spawn(1)[0] if p.solver == "grasp" else spare) for k in rows + guards]
                options = SolverOptions(samples=p.samples, iterations=p.iterations, neighbours=p.neighbours,
                                        threads=p.threads, time_limit_s=p.time_limit_s, node_limit=p.node_limit)
                sol = solve_assignment(problem, p.solver, rngs, options)
                plan = dict(mode="search" if all(a.search for a in aims[j0]) else "track",
                            move=np.asarray(sol.move, dtype=np.int64), level=np.asarray(sol.level, dtype=np.int64),
                            serve=np.asarray(sol.target, dtype=np.int64), objective=float(sol.objective),
                            optimal=bool(sol.optimal), gap=float(sol.gap))
            for j in members:
                out[j] = dict(plan, row=rows.index(j))
        return out

    def _points_each(self, aims: dict[int, list[Aim]], serve: np.ndarray) -> np.ndarray:
        """:meth:`_points` with each agent's own aims: under ``pointing: truth`` an agent points
        at the true position of the target matched to the aim it serves in its own view."""
        b = self.c.base
        points = np.array([a.aim for a in self.agents])
        if b.pointing != "truth":
            return points
        truth = self.truth.positions
        for j, mine in aims.items():
            if serve[j] < 0 or not mine:
                continue
            aim_of = gated_assignment(truth, np.array([a.mean[:3] for a in mine]), b.gate)
            for k, a in enumerate(aim_of):
                if a >= 0 and a == serve[j]:
                    points[j] = truth[k]
        return points

    def _record(self, t: int, t0: float, solve_s: float, prev: np.ndarray, n_aims: int, plan: dict,
                points: np.ndarray, level_w: np.ndarray, to_target: np.ndarray, received: np.ndarray,
                p_d: np.ndarray, scans: list, own: list[list[TrackEstimate]], sure: list[FusedTrack], mode: str,
                modes: list[str], heard: np.ndarray, mine: list[list[TrackEstimate]] | None = None) -> SwarmRecord:
        """The step's report (the confirmed tracks ``sure`` of the team's fused view, their
        members' tracks in ``own``), its metrics and its log rows; ``mine``: each agent's own
        updated tracks (``own`` when None)."""
        mine = own if mine is None else mine
        b = self.c.base
        truth = self.truth
        positions = self.positions
        interference = interference_matrix(positions, points, level_w, b.antenna).sum(axis=1)
        X = truth.detectable_positions
        report = [f for f in sure if located(f.estimate.cov, b.report_spread)
                  and f.estimate.existence * visible(f, own) > CONFIRM]
        labels = [track_label(f) for f in report]
        est = np.array([f.estimate.mean[:3] for f in report]).reshape(-1, 3)
        det = X[np.isfinite(X).all(axis=1)]
        ospa, loc, card = ospa_parts(det, est, c=b.ospa_cutoff, p=b.ospa_order)
        holder = gated_assignment(X, est, b.gate)
        target_of = np.full(len(report), -1)
        target_of[holder[holder >= 0]] = np.flatnonzero(holder >= 0)
        ids = self.log.ids
        record = SwarmRecord(
            t=t,
            step=dict(t=t, targets_present=int(truth.exists.sum()), targets_detectable=int(truth.detectable.sum()),
                      tracks=len(report), aims=n_aims, ospa=ospa, ospa_loc=loc, ospa_card=card,
                      mode=mode, objective=plan["objective"], optimal=plan["optimal"], gap=plan["gap"],
                      solve_s=solve_s, step_s=time.perf_counter() - t0),
            targets=dict(t=t, target=ids, exists=truth.exists, detectable=truth.detectable, truth=truth.positions,
                         received_w=received, held=holder >= 0,
                         track=[labels[h] if h >= 0 else "" for h in holder],
                         downed=[d is not None for d in truth.downed_at]),
            tracks=dict(t=t, track=labels, existence=[f.estimate.existence for f in report], est=est,
                        members=[len(f.members) for f in report],
                        target=[ids[k] if k >= 0 else "" for k in target_of]),
            agents=dict(t=t, prev=prev, pos=positions, level_index=plan["level"], power_w=level_w, point=points,
                        serves=[a.serves for a in self.agents],
                        detections=[int((src >= 0).sum()) for _, src in scans],
                        measurements=[len(Z) for Z, _ in scans],
                        tracks=[sum(e.existence > CONFIRM for e in tracks) for tracks in mine],
                        interference_w=interference, jammed=interference >= b.antenna.delta_w,
                        to_targets_w=to_target.sum(axis=1), mode=modes, heard=heard),
            scans=scans,
            p_d=p_d,
        )
        self.log.add(record)
        return record

    def _aims(self, t: int, predicted: list[FusedTrack], positions: np.ndarray | None = None,
              memory: SearchMemory | None = None) -> list[Aim]:
        """The step's planning aims: the confirmed predicted tracks, most likely first, then the
        search aims of the lost ones (``control.fallback: search``), at most ``MAX_AIMS``; under
        the ``comms`` faults, of one agent's view: its fused predicted tracks, the positions it
        heard this step and its own memory of the lost tracks."""
        b = self.c.base
        positions = self.positions if positions is None else positions

        def aim(label, mean, cov, search=False):
            return Aim(label, mean, cov, plan_point(mean, positions, b.team.aim, b.low, b.high), search)

        sure = [aim(track_label(f), f.estimate.mean, f.estimate.cov) for f in confirmed(predicted)[:MAX_AIMS]]
        memory = self.memory if memory is None else memory
        if memory is None:
            return sure
        lost = memory.lost(t, sure)[:MAX_AIMS - len(sure)]
        return sure + [aim(label, m, P, search=True) for label, m, P in lost]

    def _plan(self, aims: list[Aim]) -> dict:
        """The step's joint control: the solver's over the aims, or the hover fall-back."""
        b, n = self.c.base, len(self.agents)
        positions = self.positions
        if not aims:
            levels = fallback_levels(positions, np.array([a.aim for a in self.agents]), b.antenna,
                                     b.plan.constraints)
            return dict(mode="hover", move=np.zeros(n, dtype=np.int64), level=np.asarray(levels, dtype=np.int64),
                        serve=np.full(n, -1), objective=np.nan, optimal=False, gap=np.nan)
        p = b.plan
        x_bar = np.array([a.point for a in aims])
        problem = build_assignment(positions, x_bar, b.displacements, b.antenna, b.low, b.high,
                                   min(p.at_least, n), p.constraints, self.c.team_objective)
        options = SolverOptions(samples=p.samples, iterations=p.iterations, neighbours=p.neighbours,
                                threads=p.threads, time_limit_s=p.time_limit_s, node_limit=p.node_limit)
        sol = solve_assignment(problem, p.solver, [a.plan_rng for a in self.agents], options)
        return dict(mode="search" if all(a.search for a in aims) else "track", move=np.asarray(sol.move, dtype=np.int64),
                    level=np.asarray(sol.level, dtype=np.int64), serve=np.asarray(sol.target, dtype=np.int64),
                    objective=float(sol.objective), optimal=bool(sol.optimal), gap=float(sol.gap))

    def _given(self, predicted: list[FusedTrack], moves: np.ndarray, levels: np.ndarray,
               serves: list[str], positions: np.ndarray | None = None) -> tuple[list[Aim], dict]:
        """The given actions as the step's aims and plan: agent j serves the predicted team track
        that holds the track labelled ``serves[j]`` (a team track's label is one of its members',
        so a label read from the team's tracks after the last step finds its track again when
        fusion regroups it); a label no predicted track holds (the track was pruned) or ``""``
        serves nothing and the antenna keeps its last aim (mode ``hover``)."""
        b = self.c.base
        positions = self.positions if positions is None else positions
        holder = {f"a{agent}:{born}.{i}": f for f in predicted for agent, (born, i) in f.members}
        aims: list[Aim] = []
        serve = np.full(len(self.agents), -1)
        for j, label in enumerate(serves):
            f = holder.get(label) if label else None
            if f is None or f.estimate.mean is None:
                continue
            name = track_label(f)
            k = next((k for k, a in enumerate(aims) if a.label == name), len(aims))
            if k == len(aims):
                m = f.estimate.mean
                aims.append(Aim(name, m, f.estimate.cov, plan_point(m, positions, b.team.aim, b.low, b.high)))
            serve[j] = k
        return aims, dict(mode="external", move=moves, level=levels, serve=serve, objective=np.nan, optimal=False,
                          gap=np.nan)

    def _points(self, aims: list[Aim], serve: np.ndarray) -> np.ndarray:
        """Where each antenna points: its aim, or under ``pointing: truth`` the true position of
        the target matched (within metrics.gate) to the track position of the aim it serves."""
        b = self.c.base
        points = np.array([a.aim for a in self.agents])
        if b.pointing != "truth" or not aims:
            return points
        truth = self.truth.positions
        aim_of = gated_assignment(truth, np.array([a.mean[:3] for a in aims]), b.gate)
        for k, a in enumerate(aim_of):
            if a >= 0:
                points[serve == a] = truth[k]
        return points

    def _informed(self, own: list[list[TrackEstimate]], points: np.ndarray, level_w: np.ndarray) -> list[np.ndarray]:
        """Per agent and own track: its cone reached the track's mean this step (p_D > 0)."""
        b = self.c.base
        return [np.array([float(detection_probability(e.mean[:3], a.position, points[j], level_w[j], b.antenna)) > 0.0
                          for e in mine], dtype=bool) for j, (a, mine) in enumerate(zip(self.agents, own))]

    def _feed_back(self, team: list[FusedTrack], only: int | None = None) -> None:
        """Fusion feedback per cluster of two or more agents' tracks (the module docstring);
        ``only``: into that agent's filter alone (its own view, under the comms faults)."""
        for f in team:
            if len(f.members) < 2:
                continue
            e = f.estimate
            for agent, label in f.members:
                if only is None or agent == only:
                    self.agents[agent].filter.reset_track(label, e.existence, e.mean, e.cov)

    def result(self) -> SwarmResult:
        """The logs so far, as column arrays, and their summary."""
        self._whole()
        if not self.log.rows["steps"]:  # no step logged (none run, or the first interrupted): a KeyError from the summary
            raise RuntimeError("result() before the first step: call step() first")
        b = self.c.base
        tables = self.log.columns()
        summary = swarm_summary(tables, self.log.ids, name=b.name, seed=b.seed, solver=b.plan.solver,
                                n_agents=b.n_agents, gate=b.gate, downed_at=self.truth.downed_at,
                                initial=b.initial_positions, max_step=b.max_step, low=b.low, high=b.high)
        return SwarmResult(self.scenario, tables, summary)
