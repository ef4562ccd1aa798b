"""The team: agents that each decide from what they hold, and the exchange between them.

A step has three rounds of messages (the paper's Fig. 2 and Section V-D):

1. *predictions*: every working agent predicts and announces its position, aim, predicted
   estimate and its memory of the lost track; each agent forms its own x_bar (Eq. 12) from the
   predictions of this step it received, its own included;
2. *plans*: each agent solves the joint problem over the teammates it heard from this step
   (:mod:`trackjam.control.distributed`), announces its plan, and applies its part of the best
   plan it received;
3. *posteriors*: each agent updates on its own scan, announces its posterior, fuses the
   posteriors of this step it received (covariance intersection) and feeds the result back
   into its own filter.

Faults (ours, ``comms``): a message to another agent is lost with probability ``loss`` and
arrives ``delay_steps`` late; an agent can lose its publisher, its whole channel, or break down.
An agent never plans with a teammate it did not hear from this step as if it were fresh: such a
teammate is left out of the joint plan and only *guarded* at its last known position (a
receiver that Eq. (13) protects, with no moves and no say in Eq. (12)'s Xi). A teammate's late
posterior is predicted by Eq. (1) to the current step and fused with the fresh ones, and under
``fusion.share: scans`` a late scan is weighed at the particles retrodicted to its step
(``comms.stale: coast``; ``drop`` ignores both). With every message delivered, every agent holds
the same information and the team acts as one.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from trackjam.control.distributed import Proposal, adopt, own_searches
from trackjam.control.fallback import fallback_levels
from trackjam.control.planning import PlanSettings, pooled_belief, wide_belief
from trackjam.control.pursuit import AimSettings, pursuit_aim, search_aim
from trackjam.control.problem import build_problem
from trackjam.estimation.bernoulli import Estimate, Scan
from trackjam.estimation.fusion import CONFIRM, FusedEstimate, fuse_unchecked
from trackjam.radio.antenna import AntennaModel
from trackjam.simulation.agent import Agent, Message
from trackjam.world.motion import cv_coast


@dataclass(frozen=True)
class TeamSettings:
    """The fusion, fall-back and comms options the team's rounds read."""

    existence_rule: str  # fusion.existence: "mean" | "evidence"
    feedback: bool  # fusion.feedback
    searching: bool  # control.fallback == "search"
    accel_var: float  # the filters' Sigma_v scale, used to coast a lost track
    loss: float = 0.0  # comms.loss
    delay_steps: int = 0  # comms.delay_steps
    stale: str = "coast"  # comms.stale: "drop" | "coast" a teammate's late posterior or scan
    failures: tuple[tuple[int, int, str], ...] = ()  # comms.failures as (agent, step, mode)
    aim: AimSettings = AimSettings()  # control.lead, control.horizon: the aim ahead of x_bar
    search_reseed: str = "always"  # fusion.search_reseed: "always" | "evidence"
    share: str = "posteriors"  # fusion.share: "posteriors" (CI, the paper) | "scans"
    last_step: int | None = None  # the run's last step: a message due after it is never queued


@dataclass(frozen=True)
class Decision:
    """What one agent does in a step."""

    mode: str  # "track" | "search" | "hover" | "external" | "down"
    move: int
    level: int
    aim: np.ndarray | None  # where it steers its antenna; None: keeps its aim
    x_bar: np.ndarray | None  # its planning aim of Eq. (12)
    objective: float  # Xi of the adopted plan (NaN unless tracking)
    heard: int  # agents whose predictions of this step it planned with, itself included
    optimal: bool = False  # the adopted plan is proven optimal (exact within its budget)
    gap: float = float("nan")  # its certified gap to the optimum; NaN: no certificate
    closed_in: bool = False  # the adopted plan closes in (control.close_in, ours)


class Exchange:
    """Delivers each round's messages: to the sender at once, to every other agent unless the
    message is lost or a failure stops it, ``delay_steps`` later."""

    def __init__(self, n: int, settings: TeamSettings, rng: np.random.Generator) -> None:
        self.n, self.s, self.rng = n, settings, rng
        # (arrival step, kind) -> [(receiver, message)] in the order sent: a round takes its own
        # list, where rescanning every message in flight three times a step had made a step at
        # comms.delay_steps 1000 with 16 agents take 2.6 s
        self.pending: dict[tuple[int, str], list[tuple[int, Message]]] = {}
        self._failures: dict[int, list[tuple[int, str]]] = {}  # agent -> (first step, mode), each failure once
        for a, step, mode in settings.failures:
            self._failures.setdefault(a, []).append((step, mode))

    def failed(self, agent: int, t: int, modes: tuple[str, ...]) -> bool:
        return any(t >= step and mode in modes for step, mode in self._failures.get(agent, ()))

    def down(self, agent: int, t: int) -> bool:
        return self.failed(agent, t, ("breakdown",))

    def send(self, t: int, kind: str, messages: list[Message]) -> list[list[Message]]:
        """One round: every agent's inbox of the messages of ``kind`` arriving at step ``t``."""
        lost = self.rng.random((self.n, self.n)) < self.s.loss  # drawn every round: one stream
        inboxes: list[list[Message]] = [[] for _ in range(self.n)]
        for m in messages:
            inboxes[m.sender].append(m)
            if self.failed(m.sender, t, ("publisher", "channel", "breakdown")):
                continue
            if self.s.last_step is not None and t + self.s.delay_steps > self.s.last_step:
                continue  # due after the run ends: at comms.delay_steps 1000 it had queued millions
            waiting = self.pending.setdefault((t + self.s.delay_steps, kind), [])
            for r in range(self.n):
                if r != m.sender and not lost[m.sender, r]:
                    waiting.append((r, m))
        for r, m in self.pending.pop((t, kind), ()):  # what arrives now; other rounds' wait for theirs
            if not self.failed(r, t, ("channel", "breakdown")):
                inboxes[r].append(m)
        for key in [key for key in self.pending if key[0] < t]:  # a round that did not come: dropped, as before
            del self.pending[key]
        return [sorted(box, key=lambda m: (m.sender, m.stamp)) for box in inboxes]


class Team:
    def __init__(self, agents: list[Agent], settings: TeamSettings, rng: np.random.Generator) -> None:
        self.agents = agents
        self.settings = settings
        self.exchange = Exchange(len(agents), settings, rng)
        self.inbox: list[list[Message]] = [[] for _ in agents]  # this step's predictions received
        # latest prediction from each teammate; at launch every agent knows where the team starts
        briefing = {a.index: Message(a.index, "prediction", 0, position=a.position.copy(), aim=a.aim.copy())
                    for a in agents}
        self.known: list[dict[int, Message]] = [dict(briefing) for _ in agents]
        self.t = 0

    @property
    def positions(self) -> np.ndarray:
        return np.array([a.position for a in self.agents])

    @property
    def aims(self) -> np.ndarray:
        return np.array([a.aim for a in self.agents])

    def working(self, t: int | None = None) -> list[int]:
        t = self.t if t is None else t
        return [a.index for a in self.agents if not self.exchange.down(a.index, t)]

    def predict(self, t: int, belief_samples: int = 0) -> None:
        """Round 1: working agents predict (Section V-A) and announce."""
        self.t = t
        q = self.settings.accel_var
        sent = [self.agents[j].predict(t, q, belief_samples) for j in self.working()]
        inboxes = self.exchange.send(t, "prediction", sent)
        for j, box in enumerate(inboxes):
            for m in box:
                if m.sender not in self.known[j] or self.known[j][m.sender].stamp <= m.stamp:
                    self.known[j][m.sender] = m
            self.inbox[j] = [m for m in box if m.stamp == t]

    def fresh(self, j: int) -> list[Message]:
        """The predictions of this step agent j holds, its own included, in sender order."""
        return self.inbox[j]

    def decide(self, displacements: np.ndarray, ant: AntennaModel, low: np.ndarray, high: np.ndarray,
               plan: PlanSettings, actions=None, told: np.ndarray | None = None) -> tuple[list[Decision], float]:
        """Round 2: every working agent plans and proposes; each applies the best plan it
        received. ``actions`` (moves, levels) overrides the plans. ``told`` (an oracle's, ours:
        the target's true position) replaces every agent's x_bar, planned for at that point.
        Returns the decisions and the wall time of planning."""
        t0 = time.perf_counter()
        working = self.working()
        if told is not None:
            x_bars = {j: np.array(told, dtype=float) for j in working}
        else:
            x_bars = self._planning_aims(working, low, high, own=plan.own_aims)
        decisions: list[Decision | None] = [None] * len(self.agents)
        for j in range(len(self.agents)):
            if j not in working:
                decisions[j] = Decision("down", 0, 0, None, None, np.nan, 0)
        if actions is not None:
            moves, levels = (np.asarray(a, dtype=np.int64) for a in actions)
            for j in working:
                decisions[j] = Decision("external", int(moves[j]), int(levels[j]), x_bars[j], x_bars[j], np.nan,
                                        len(self.fresh(j)))
            # the plan round runs with no plans, so that its losses are drawn as a solver's step
            # draws them: an external controller meets the same lost messages on the same seed
            self.exchange.send(self.t, "plan", [])
            return decisions, time.perf_counter() - t0
        proposals = self._proposals(working, x_bars, displacements, ant, low, high, plan, t0, told is not None)
        inboxes = self.exchange.send(self.t, "plan", [Message(p.sender, "plan", self.t, plan=p) for p in proposals])
        own = {p.sender: p for p in proposals} if plan.own_aims else None
        for j in working:
            # Eq. (11) as printed (greedy_aim: own): each agent applies the plan it made alone
            best = own[j] if own is not None else adopt([m.plan for m in inboxes[j] if m.stamp == self.t], j)
            move, level = best.control_of(j)
            objective = best.objective if best.mode == "track" else np.nan
            decisions[j] = Decision(best.mode, move, level, best.aim, x_bars[j], objective, len(self.fresh(j)),
                                    best.optimal, best.gap, best.closed_in)
        return decisions, time.perf_counter() - t0

    def _planning_aims(self, working, low: np.ndarray, high: np.ndarray,
                       own: bool = False) -> dict[int, np.ndarray | None]:
        """Each working agent's x_bar (:func:`pursuit_aim` of the predictions it received this
        step), computed once per distinct inbox: agents that received the same messages (every
        agent, when none is lost) get the same aim, each its own copy. ``own`` (Eq. 11 as printed,
        ``control.greedy_aim: own``): an agent whose own predicted existence exceeds 0.5 aims at its
        own prediction x_tilde^j instead."""
        aims: dict[tuple[int, ...], np.ndarray | None] = {}
        out = {}
        for j in working:
            heard = self.fresh(j)
            mine = [m for m in heard if m.sender == j]
            if own and mine and mine[0].estimate.existence > CONFIRM:
                out[j] = pursuit_aim([mine[0].estimate], np.array([mine[0].position]), self.settings.aim, low, high)
                continue
            key = tuple(id(m) for m in heard)  # the same message objects, in the same order
            if key not in aims:
                aims[key] = pursuit_aim([m.estimate for m in heard], np.array([m.position for m in heard]),
                                        self.settings.aim, low, high)
            out[j] = None if aims[key] is None else aims[key].copy()
        return out

    def _proposals(self, working, x_bars, displacements, ant, low, high, plan: PlanSettings,
                   t0: float, told: bool = False) -> list[Proposal]:
        """Each working agent's plan over the teammates it heard from this step. Agents holding
        the same problem solve it together (deterministic solvers once; GRASP one search each).
        ``told``: x_bar is the true position, planned for at that point, never over the belief."""
        groups: dict[tuple, list[int]] = {}
        hover: list[Proposal] = []
        for j in working:
            heard = self.fresh(j)
            rows = tuple(m.sender for m in heard)
            guards = tuple(sorted(k for k in self.known[j] if k not in rows))
            x_bar = x_bars[j]
            if x_bar is None and plan.fallback != "search":
                aims = np.array([m.aim for m in heard])
                positions = np.array([m.position for m in heard])
                levels = fallback_levels(positions, aims, ant, plan.constraints)
                hover.append(Proposal(j, rows, "hover", None, np.zeros(len(rows), dtype=np.int64),
                                      np.asarray(levels, dtype=np.int64), np.nan))
                continue
            aim = x_bar if x_bar is not None else search_aim(
                [m.coasted for m in heard if m.coasted is not None], [m.estimate for m in heard],
                np.array([m.aim for m in heard]), np.array([m.position for m in heard]), self.settings.aim, low, high)
            key = (rows, guards, aim.tobytes(), tuple(m.position.tobytes() for m in heard),
                   tuple(self.known[j][k].position.tobytes() for k in guards), x_bar is None)
            groups.setdefault(key, []).append(j)
        out = hover
        for key, members in groups.items():
            rows, guards, _, _, _, searching = key
            j0 = members[0]
            heard = self.fresh(j0)
            aim = np.frombuffer(key[2])
            positions = np.array([m.position for m in heard] + [self.known[j0][k].position for k in guards])
            samples = weights = None
            n_detect = plan.at_least
            if plan.belief_samples and not told and wide_belief([m.estimate for m in heard], plan.belief_spread):
                # tracking: the believers' predicted densities; searching: wherever the team's can be
                sampled = [m.belief for m in heard if searching or m.estimate.existence > CONFIRM]
                samples, weights = pooled_belief(sampled)
                if plan.belief_at_least is not None:
                    n_detect = plan.belief_at_least
            problem = build_problem(positions, aim, displacements, ant, low, high,
                                    min(n_detect, len(rows)), plan.constraints, samples, weights)
            if guards:
                problem = problem.guarded(len(rows))
            found = own_searches(problem, plan.solver, [rows.index(j) for j in members],
                                 [self.agents[j].plan_rng for j in members], plan.samples, plan.iterations,
                                 plan.neighbours, plan.threads, _remaining(plan.time_limit_s, t0), plan.node_limit,
                                 plan.close_in)
            mode = "search" if searching else "track"
            for j, (sol, value) in zip(members, found):
                n = len(rows)
                out.append(Proposal(j, rows, mode, aim.copy(), sol.move[:n], sol.level[:n], value,
                                    sol.optimal, sol.gap, sol.closed_in))
        return sorted(out, key=lambda p: p.sender)

    def apply(self, decisions: list[Decision], displacements: np.ndarray) -> None:
        for a, d in zip(self.agents, decisions):
            if d.aim is not None:
                a.aim = np.array(d.aim, dtype=float)
            a.position = a.position + displacements[d.move]

    def update(self, scans: list[np.ndarray], points: np.ndarray, level_w: np.ndarray) -> list[Message | None]:
        """Each working agent updates its filter on its own scan (Section V-A) and, with
        ``fusion.share: scans``, on every teammate's scan of this step it received and, under
        ``comms.stale: coast``, on every late one that arrived, weighed at its particles
        retrodicted to the scan's step (:meth:`Scan.log_factors`)."""
        out: list[Message | None] = [None] * len(self.agents)
        working = self.working()
        others: dict[int, list] = {j: [] for j in working}
        if self.settings.share == "scans":
            ant = self.agents[working[0]].filter.ant if working else None
            sent = [Message(j, "scan", self.t,
                            scan=Scan.of(scans[j], self.agents[j].position, points[j], float(level_w[j]), ant))
                    for j in working]
            inboxes = self.exchange.send(self.t, "scan", sent)
            late = self.settings.stale == "coast"
            others = {j: [m.scan if m.stamp == self.t else m.scan.late(self.t - m.stamp) for m in inboxes[j]
                          if m.sender != j and (m.stamp == self.t or late)] for j in working}
        for j in working:
            prior = next(m for m in self.inbox[j] if m.sender == j).estimate.existence
            out[j] = self.agents[j].update(self.t, scans[j], points[j], float(level_w[j]), prior, others[j])
        return out

    def fuse(self, posteriors: list[Message | None]) -> FusedEstimate | None:
        """Round 3: posteriors are announced; each working agent fuses the ones of this step it
        received, remembers the team's track and, with ``fusion.feedback``, reseeds its filter
        (a searching agent from its lost track coasted). Returns the team's report: the fusion
        of the lowest-index working agent (None when every agent is down)."""
        s = self.settings
        if s.share == "scans":
            return self._own_estimates(posteriors)
        inboxes = self.exchange.send(self.t, "posterior", [m for m in posteriors if m is not None])
        report = None
        fused_by_inbox: dict[tuple[int, ...], FusedEstimate] = {}  # agents holding the same messages fuse alike
        for j in self.working():
            a = self.agents[j]
            box = [m for m in inboxes[j] if m.stamp == self.t]
            if s.stale == "coast":
                box += coasted_posteriors([m for m in inboxes[j] if m.stamp < self.t], self.t, s.accel_var)
            key = tuple(id(m) for m in box)
            if key not in fused_by_inbox:
                hidden = box and box[0].visibility is not None
                fused_by_inbox[key] = fuse_unchecked([m.estimate for m in box], predicted=[m.prior_existence for m in box],
                                           rule=s.existence_rule,
                                           log_evidence=[m.log_evidence for m in box] if hidden else None,
                                           visibility=[m.visibility for m in box] if hidden else None)
            fused = fused_by_inbox[key]
            report = fused if report is None else report
            a.remember(fused.existence, fused.mean, fused.cov)
            if not s.feedback:
                continue
            if fused.mean is None and s.searching and a.last_track is not None:
                if s.search_reseed == "evidence" and own_scan_raised(j, box):
                    a.filter.reset_to(fused.existence, visible=fused.visible)  # keep the particles its own scan supports
                    continue
                mean, cov = a.coasted_track(s.accel_var)
                a.filter.reset_to(fused.existence, mean, cov, visible=fused.visible)
            else:
                a.filter.reset_to(fused.existence, fused.mean, fused.cov, visible=fused.visible)
        return report

    def note_jamming(self, points: np.ndarray, levels_w: np.ndarray) -> None:
        """``filter.response``: every working agent's filter weighs the step's transmissions of
        the whole team (each agent adopted a plan holding every teammate's move, level and aim)."""
        positions = self.positions
        for j in self.working():
            self.agents[j].filter.note_jamming(positions, points, levels_w)

    def _own_estimates(self, posteriors: list[Message | None]) -> FusedEstimate | None:
        """fusion.share: scans: every agent's filter already holds the scans it received, so its
        own posterior is its team estimate; the report is the lowest-index working agent's."""
        report = None
        for j in self.working():
            est = posteriors[j].estimate
            located = est.existence > CONFIRM
            fused = FusedEstimate(est.existence, est.mean if located else None, est.cov if located else None,
                                  np.zeros(0), None if posteriors[j].visibility is None else self.agents[j].filter.nu)
            report = fused if report is None else report
            self.agents[j].remember(fused.existence, fused.mean, fused.cov)
        return report


def latest_by_sender(late: list[Message]) -> list[Message]:
    """Of the late messages that arrived, each sender's latest, in sender order."""
    latest: dict[int, Message] = {}
    for m in late:
        if m.sender not in latest or latest[m.sender].stamp < m.stamp:
            latest[m.sender] = m
    return [latest[sender] for sender in sorted(latest)]


def coasted_posteriors(late: list[Message], t: int, accel_var: float) -> list[Message]:
    """``comms.stale: coast`` (ours): of the late posteriors that arrived, each sender's latest
    only, its estimate predicted by Eq. (1) from its step to ``t`` (existence, and the predicted
    existence it started from, as sent)."""
    out = []
    for m in latest_by_sender(late):
        est = m.estimate
        if est.mean is not None:
            mean, cov = cv_coast(est.mean, est.cov, accel_var, t - m.stamp)
            est = Estimate(est.existence, mean, cov)
        out.append(replace(m, estimate=est))
    return out


def own_scan_raised(index: int, posteriors: list[Message]) -> bool:
    """Agent ``index``'s own scan carried evidence for the target: e_t > e_{t|t-1}."""
    own = next(m for m in posteriors if m.sender == index)
    return own.estimate.existence > own.prior_existence


SEARCH_CHUNK_S = 0.05  # exact checks its clock between chunks of about 20 ms: keep one chunk in hand


def _remaining(budget_s: float | None, t0: float) -> float | None:
    """What is left of the decision's time budget (``control.time_limit_s``) since ``t0``, less
    one search chunk: the tables a search needs are built on the same clock, so the search
    stops within the budget unless building them alone took longer (milliseconds at the
    paper's 79 candidates; about 3.5 s at 4,683 candidates or 64 agents, which the budget cannot
    cut short). A search always gets a millisecond to return a feasible plan."""
    if budget_s is None:
        return None
    return max(budget_s - (time.perf_counter() - t0) - SEARCH_CHUNK_S, 1e-3)
