"""The PettingZoo ``ParallelEnv`` over the swarm engine (:class:`trackjam.simulation.swarm.
SwarmSimulation`): a scenario with several ``targets``, e.g. ``swarm-3``.

An action is ``[move, level, slot]``: an index into Eq. (3)'s displacement set (0 = hover), an
index into the transmit levels L, and the track the agent's antenna serves: 0 none (the antenna
keeps pointing at its last aim), S in 1..M the track in slot S of the observation the agent
acted on. The environment keeps, per agent, the label each of its slots showed and hands the
engine that label, so a slot means the same track from the observation to the step that
applies it, whatever the slots hold by then; the engine serves the predicted track of the
agent's own view holding that label (fusion may regroup it under another label), and when none
does (the track was pruned, or under the ``comms`` faults the agent no longer holds it), or the
slot was empty, the antenna keeps its last aim (the info says ``track_gone``).

Each agent observes its own view: without the ``comms`` faults every message arrives and every
agent's view is the team's (``sim.sure``); under them (``sim.distributed``) agent j's slots hold
the confirmed tracks of its own fused view (``sim.views[j]``) and its teammates' positions are
what it last heard (``sim.known[j]``). An agent that broke down (``comms.failures``, mode
``down``) stays in the episode: its action is ignored and its info says ``mode: down``.
Observations and the global state: :mod:`trackjam.env.swarm_observation`; the reward:
:mod:`trackjam.env.reward`. An episode terminates when every target is downed or has flown out
of the area, and is truncated after ``steps``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from gymnasium import spaces

from trackjam.control.assignment import ASSIGNMENT_SOLVERS
from trackjam.env.parallel import Planned, TrackjamParallelEnv, checked_action, figure_pixels, hover_outside
from trackjam.env.reward import swarm_reward_terms, team_reward
from trackjam.env.swarm_observation import (
    checked_slots,
    swarm_observation_bounds,
    swarm_observe,
    swarm_state,
    swarm_state_bounds,
)
from trackjam.errors import ConfigError
from trackjam.estimation.lmb_fusion import fuse_tracks_unchecked
from trackjam.simulation.build import figure_settings
from trackjam.simulation.swarm import MAX_AIMS, SwarmRecord, SwarmSimulation, confirmed, track_label
from trackjam.world.moves import admissible_moves

if TYPE_CHECKING:  # the scenario is only handed on: simulation/build.py reads it
    from trackjam.estimation.lmb_fusion import FusedTrack
    from trackjam.simulation.build import Scenario


def member_labels(track: FusedTrack) -> set[str]:
    """The labels of a team track's members, ``aA:B.I`` as :func:`track_label` writes them: a
    track served under any of them is this one."""
    return {f"a{agent}:{born}.{i}" for agent, (born, i) in track.members}


class SwarmParallelEnv(TrackjamParallelEnv):
    """The team against several targets; ``track_slots`` (M) is how many of its view's confirmed
    tracks an agent observes and may serve (default, or None: as many as the engine plans at, 4)."""

    metadata = {"name": "trackjam_swarm_v0", "render_modes": ["rgb_array", "replay"], "render_fps": 1}
    ACTION_WORDS = "[move, level, track slot]"

    def __init__(self, scenario: Scenario, jam_penalty: float = 1.0, render_mode: str | None = None,
                 replay_path: str = "replay.html", track_slots: int | None = MAX_AIMS,
                 render_size: tuple[int, int] | None = None) -> None:
        self.track_slots = checked_slots(MAX_AIMS if track_slots is None else track_slots)
        # per agent, the label each of its occupied slots showed in its last observation
        self._slot_labels: list[list[str]] = []
        super().__init__(scenario, jam_penalty=jam_penalty, render_mode=render_mode, replay_path=replay_path,
                         render_size=render_size)

    # -- the hooks of TrackjamParallelEnv ----------------------------------------------------

    def _check_targets(self, scenario: Scenario) -> None:
        if len(scenario.target_list) < 2:
            raise ConfigError("SwarmParallelEnv runs the swarm engine, for several targets; this scenario has one: "
                              "trackjam.env.parallel_env(scenario) gives the one-target environment")

    def _engine(self, scenario: Scenario) -> SwarmSimulation:
        return SwarmSimulation(scenario)

    def _spaces(self) -> None:
        b = self.sim.c.base
        n = len(self.possible_agents)
        n_moves, n_levels = len(b.displacements), len(b.antenna.levels_w)
        lo, hi = swarm_observation_bounds(n, self.track_slots, b.low, b.high)
        self.action_spaces = {a: spaces.MultiDiscrete([n_moves, n_levels, self.track_slots + 1])
                              for a in self.possible_agents}
        self.observation_spaces = {a: spaces.Box(lo, hi, dtype=np.float32) for a in self.possible_agents}
        self.state_space = spaces.Box(*swarm_state_bounds(n, len(self.sim.c.ids), n_levels, b.low, b.high),
                                      dtype=np.float32)

    @property
    def solvers(self) -> dict:
        """The several-target solvers (:data:`trackjam.control.assignment.ASSIGNMENT_SOLVERS`)."""
        return ASSIGNMENT_SOLVERS

    @property
    def target_ids(self) -> list[str]:
        """The targets' ids, in the order of the state's ``targetI`` blocks and the infos' arrays."""
        return [str(i) for i in self.sim.c.ids]

    # -- episode ---------------------------------------------------------------------------

    def _first_observations(self) -> dict:
        self._levels = np.zeros(len(self.possible_agents), dtype=np.int64)
        self._held = np.zeros(len(self.sim.c.ids), dtype=bool)
        return self._observations()

    def _reset_info(self, j: int) -> dict:
        return {"slots": self._slots_shown(j)}

    def _slots_shown(self, j: int) -> list[str]:
        """The label each of agent j's slots holds now ("" for an empty one), what its action's
        slot will name."""
        labels = self._slot_labels[j]
        return labels + [""] * (self.track_slots - len(labels))

    def state(self) -> np.ndarray:
        """The global state, for a centralised critic (``trackjam.env.swarm_state_layout``
        names its entries): every agent's position and level, every target's true state, whether
        it exists, is detectable and is held by a reported track, and the time."""
        self._check_state()
        sim, b = self.sim, self.sim.c.base
        truth = sim.truth
        return swarm_state(np.clip(sim.positions, b.low, b.high), self._levels, truth.states, truth.exists,
                           truth.detectable, self._held, sim.t / b.steps)

    def _action_mask(self, j: int) -> np.ndarray:
        """Agent j's action mask, MultiDiscrete-style: the moves that keep it inside the area,
        every level, then the slots: "none" and each occupied slot."""
        b = self.sim.c.base
        moves = admissible_moves(self.sim.agents[j].position, b.displacements, b.low, b.high)
        slots = np.arange(self.track_slots + 1) <= len(self._slot_labels[j])
        return np.concatenate([moves, np.ones(len(b.antenna.levels_w), dtype=bool), slots])

    def _external_step(self, actions: dict) -> tuple[SwarmRecord, np.ndarray]:
        b = self.sim.c.base
        n = len(self.possible_agents)
        moves, levels, slots = (np.zeros(n, dtype=np.int64) for _ in range(3))
        for name in self.agents:
            j = self._index[name]
            moves[j], levels[j], slots[j] = checked_action(name, actions[name], self.action_spaces[name],
                                                           self.ACTION_WORDS)
        hovered = hover_outside(moves, self.sim.positions, b.displacements, b.low, b.high)
        named = [self._slots_shown(j)[s - 1] if s else "" for j, s in enumerate(slots)]
        record = self.sim.step((moves, levels, named))
        self._named = (slots, named)
        return record, hovered

    def _plan_with(self, solver: str) -> None:
        c = self.sim.c
        if c.base.plan.solver != solver:  # the engine plans with the settings it was built with
            self.sim.c = replace(c, base=replace(c.base, plan=replace(c.base.plan, solver=solver)))

    def _planned_step(self, planned: list[Planned]) -> SwarmRecord:
        self._plan_with(self._planned_solver(planned))
        shown = [self._slots_shown(j) for j in range(len(self.possible_agents))]
        record = self.sim.step()
        served = [str(s) for s in record.agents["serves"]]  # the solver's choice, as an action would name it
        self._named = (np.array([shown[j].index(s) + 1 if s and s in shown[j] else 0 for j, s in enumerate(served)]),
                       served)
        return record

    def _outcome(self, record: SwarmRecord, hovered: np.ndarray):
        sim, b = self.sim, self.sim.c.base
        ag = record.agents
        xi_k, v = swarm_reward_terms(record.p_d, ag["interference_w"], b.antenna.delta_w, b.plan.at_least)
        xi = float(xi_k.sum())
        reward = team_reward(xi, v, self.jam_penalty)
        truth = sim.truth
        over = [d is not None or t.gone for d, t in zip(truth.downed_at, truth.targets)]
        terminated = all(over)
        if terminated:
            end = f"every target downed or gone by step {record.t}"
        truncated = not terminated and sim.done
        if terminated or truncated:
            self._ended = end if terminated else f"truncated after {b.steps} steps"
        self._levels = np.asarray(ag["level_index"], dtype=np.int64)
        self._held = np.asarray(record.targets["held"], dtype=bool)
        D = b.displacements
        moves = np.argmin(np.linalg.norm((ag["pos"] - ag["prev"])[:, None, :] - D[None], axis=2), axis=1)
        slots, named = self._named
        served = [str(s) for s in ag["serves"]]
        # a broken agent's action was ignored: its move was not replaced and its track not lost
        up = [str(m) != "down" for m in ag["mode"]]
        obs = self._observations()
        live = list(self.agents)
        infos = {
            a: {
                "t": record.t, "move": int(moves[j]), "level": int(ag["level_index"][j]), "slot": int(slots[j]),
                "track": named[j], "served": served[j], "track_gone": up[j] and bool(named[j]) and not served[j],
                "hovered": up[j] and bool(hovered[j]), "p_d": record.p_d[j].copy(),
                "interference_w": float(ag["interference_w"][j]), "jammed": bool(ag["jammed"][j]),
                "violation": float(v[j]), "xi": xi, "xi_targets": xi_k.copy(), "mode": str(ag["mode"][j]),
                "slots": self._slots_shown(j), "action_mask": self._action_mask(j),
                **({"end": self._ended} if (terminated or truncated) else {}),
            }
            for a, j in ((a, self._index[a]) for a in live)
        }
        if terminated or truncated:
            self.agents = []
        return (obs, {a: reward for a in live}, {a: terminated for a in live}, {a: truncated for a in live},
                infos)

    def _views(self) -> list[list[FusedTrack]]:
        """Each agent's confirmed tracks, most likely first (:func:`confirmed`). Without the
        ``comms`` faults every agent's view is the team's, ``sim.sure`` (before the first step the
        cue's tracks). Under them each agent's own fused view after the last step,
        ``sim.views[j]`` (none while it is down), and before the first step its own filter's
        tracks (the cue's, as it holds them, under its own labels: those its first predicted view
        holds whoever it hears)."""
        sim = self.sim
        n = len(self.possible_agents)
        if not sim.distributed:
            return [sim.sure] * n
        if sim.t == 0:
            return [confirmed(fuse_tracks_unchecked([a.filter.estimates() if k == j else [] for k, a in
                                                     enumerate(sim.agents)])) for j in range(n)]
        seen: dict[int, list[FusedTrack]] = {}  # agents that fused the same messages share a view
        for view in sim.views:
            if id(view) not in seen:
                seen[id(view)] = confirmed(view)
        return [seen[id(view)] for view in sim.views]

    def _mates(self, j: int, positions: np.ndarray) -> list[tuple[np.ndarray, bool, float]]:
        """What agent j last heard of each teammate, in index order: (position clipped to the
        area, heard this step, age as a share of the episode). Without the ``comms`` faults every
        message arrives: the position after the move, heard, age 0. Under them the position of
        the last prediction that reached it (``sim.known[j][k]``, announced before that step's
        move), the briefing (k's start, at step 0) when none did."""
        sim, b = self.sim, self.sim.c.base
        n = len(self.possible_agents)
        if not sim.distributed:
            return [(positions[k], True, 0.0) for k in range(n) if k != j]
        out = []
        for k in range(n):
            if k != j:
                stamp, u = sim.known[j][k]
                out.append((np.clip(u, b.low, b.high), stamp == sim.t, (sim.t - stamp) / b.steps))
        return out

    def _observations(self) -> dict:
        """Every agent's observation, and its slots' labels for its next action."""
        sim, b = self.sim, self.sim.c.base
        views = [view[: self.track_slots] for view in self._views()]
        self._slot_labels = [[track_label(f) for f in view] for view in views]
        serves = [a.serves for a in sim.agents]
        n = len(serves)
        positions = np.clip(sim.positions, b.low, b.high)
        fraction = sim.t / b.steps
        out = {}
        for a, j in ((a, self._index[a]) for a in self.possible_agents):
            tracks = []
            for f in views[j]:
                m = member_labels(f)
                # under the faults no message says what a teammate served: the agent knows its own antenna
                share = float(serves[j] in m) / n if sim.distributed else sum(s in m for s in serves) / n
                tracks.append((f.estimate.mean, f.estimate.existence, serves[j] in m, share))
            out[a] = swarm_observe(positions[j], tracks, self._mates(j, positions), self.track_slots, fraction)
        return out

    # -- rendering -------------------------------------------------------------------------

    def render(self):
        """``rgb_array``: the run's figure of the episode so far (the several-target run.png) as
        an (H, W, 3) uint8 array (fitted to ``render_size`` when one was given); ``replay``:
        writes the several-target interactive replay of the episode so far to ``replay_path``
        and returns that path."""
        if not self._ready_to_render():
            return None
        res = self.sim.result()
        settings = replace(figure_settings(res.scenario), solver=self._acted(res.steps["mode"]))
        if self.render_mode == "replay":
            from trackjam.files import atomic_write
            from trackjam.viz.swarm_replay import write_swarm_replay

            return atomic_write(self.replay_path, lambda p: write_swarm_replay(res.tables, settings, p))
        from trackjam.viz.swarm import plot_swarm

        return self._frame(figure_pixels(lambda p: plot_swarm(res.tables, settings, p)))

    def _acted(self, modes) -> str:
        """Who chose the episode's actions, for the figure's title (the steps' ``mode``)."""
        acted = set(np.asarray(modes).tolist())
        if acted <= {"external"}:
            return "external"
        solver = self.sim.c.base.plan.solver
        return f"{solver} and external" if "external" in acted else solver
