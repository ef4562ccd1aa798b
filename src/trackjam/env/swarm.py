"""The PettingZoo ``ParallelEnv`` over the swarm engine (:class:`trackjam.simulation.swarm.
SwarmSimulation`): a scenario with several ``targets``, e.g. ``swarm-3``.

An action is ``[move, level, slot]``: an index into Eq. (3)'s displacement set (0 = hover), an
index into the transmit levels L, and the track the agent's antenna serves: 0 none (the antenna
keeps pointing at its last aim), S in 1..M the track in slot S of the observation the agent
acted on. The environment keeps the label each slot showed and hands the engine that label, so
a slot means the same track from the observation to the step that applies it, whatever the
slots hold by then; the engine serves the predicted team track holding that label (fusion may
regroup it under another team label), and when none does (the track was pruned), or the slot
was empty, the antenna keeps its last aim (the info says ``track_gone``). Observations and the
global state: :mod:`trackjam.env.swarm_observation`; the reward: :mod:`trackjam.env.reward`. An
episode terminates when every target is downed or has flown out of the area, and is truncated
after ``steps``.
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
from trackjam.simulation.build import figure_settings
from trackjam.simulation.swarm import MAX_AIMS, SwarmRecord, SwarmSimulation, track_label
from trackjam.world.moves import admissible_moves

if TYPE_CHECKING:  # the scenario is only handed on: simulation/build.py reads it
    from trackjam.estimation.lmb_fusion import FusedTrack
    from trackjam.simulation.build import Scenario


def member_labels(track: FusedTrack) -> set[str]:
    """The labels of a team track's members, ``aA:B.I`` as :func:`track_label` writes them: a
    track served under any of them is this one."""
    return {f"a{agent}:{born}.{i}" for agent, (born, i) in track.members}


class SwarmParallelEnv(TrackjamParallelEnv):
    """The team against several targets; ``track_slots`` (M) is how many of the team's confirmed
    tracks an agent observes and may serve (default, or None: as many as the engine plans at, 4)."""

    metadata = {"name": "trackjam_swarm_v0", "render_modes": ["rgb_array"], "render_fps": 1}
    ACTION_WORDS = "[move, level, track slot]"

    def __init__(self, scenario: Scenario, jam_penalty: float = 1.0, render_mode: str | None = None,
                 replay_path: str = "replay.html", track_slots: int | None = MAX_AIMS,
                 render_size: tuple[int, int] | None = None) -> None:
        self.track_slots = checked_slots(MAX_AIMS if track_slots is None else track_slots)
        self._slot_labels: list[str] = []  # the label each occupied slot showed in the last observation
        super().__init__(scenario, jam_penalty=jam_penalty, render_mode=render_mode, replay_path=replay_path,
                         render_size=render_size)

    # -- the hooks of TrackjamParallelEnv ----------------------------------------------------

    def _check_targets(self, scenario: Scenario) -> None:
        if len(scenario.target_list) < 2:
            raise ConfigError("SwarmParallelEnv runs the swarm engine, for several targets; this scenario has one: "
                              "trackjam.env.parallel_env(scenario) gives the one-target environment")

    def _check_replay(self, path) -> None:
        raise ValueError("render_mode: 'replay' is not available with several targets (the swarm engine writes "
                         "no replay); take 'rgb_array', the run's figure")

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

    def _reset_info(self) -> dict:
        return {"slots": self._slots_shown()}

    def _slots_shown(self) -> list[str]:
        """The label each slot holds now ("" for an empty one), what an action's slot will name."""
        return self._slot_labels + [""] * (self.track_slots - len(self._slot_labels))

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
        slots = np.arange(self.track_slots + 1) <= len(self._slot_labels)
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
        shown = self._slots_shown()
        named = [shown[s - 1] if s else "" for s in slots]
        record = self.sim.step((moves, levels, named))
        self._named = (slots, named)
        return record, hovered

    def _plan_with(self, solver: str) -> None:
        c = self.sim.c
        if c.base.plan.solver != solver:  # the engine plans with the settings it was built with
            self.sim.c = replace(c, base=replace(c.base, plan=replace(c.base.plan, solver=solver)))

    def _planned_step(self, planned: list[Planned]) -> SwarmRecord:
        self._plan_with(self._planned_solver(planned))
        shown = self._slots_shown()
        record = self.sim.step()
        served = [str(s) for s in record.agents["serves"]]  # the solver's choice, as an action would name it
        self._named = (np.array([shown.index(s) + 1 if s and s in shown else 0 for s in served]), served)
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
        obs = self._observations()
        shown = self._slots_shown()
        live = list(self.agents)
        infos = {
            a: {
                "t": record.t, "move": int(moves[j]), "level": int(ag["level_index"][j]), "slot": int(slots[j]),
                "track": named[j], "served": served[j], "track_gone": bool(named[j]) and not served[j],
                "hovered": bool(hovered[j]), "p_d": record.p_d[j].copy(),
                "interference_w": float(ag["interference_w"][j]), "jammed": bool(ag["jammed"][j]),
                "violation": float(v[j]), "xi": xi, "xi_targets": xi_k.copy(), "mode": str(ag["mode"][j]),
                "slots": list(shown), "action_mask": self._action_mask(j),
                **({"end": self._ended} if (terminated or truncated) else {}),
            }
            for a, j in ((a, self._index[a]) for a in live)
        }
        if terminated or truncated:
            self.agents = []
        return (obs, {a: reward for a in live}, {a: terminated for a in live}, {a: truncated for a in live},
                infos)

    def _observations(self) -> dict:
        """Every agent's observation, and the slots' labels for the next actions."""
        sim, b = self.sim, self.sim.c.base
        tracks = sim.sure[: self.track_slots]
        self._slot_labels = [track_label(f) for f in tracks]
        serves = [a.serves for a in sim.agents]
        n = len(serves)
        members = [member_labels(f) for f in tracks]
        share = [sum(s in m for s in serves) / n for m in members]
        positions = np.clip(sim.positions, b.low, b.high)
        fraction = sim.t / b.steps
        return {
            a: swarm_observe(j, positions, [(f.estimate.mean, f.estimate.existence, serves[j] in m, sh)
                                            for f, m, sh in zip(tracks, members, share)],
                             self.track_slots, fraction)
            for a, j in ((a, self._index[a]) for a in self.possible_agents)
        }

    # -- rendering -------------------------------------------------------------------------

    def render(self):
        """``rgb_array``: the run's figure of the episode so far (the several-target run.png) as
        an (H, W, 3) uint8 array (fitted to ``render_size`` when one was given)."""
        if not self._ready_to_render():
            return None
        from trackjam.viz.swarm import plot_swarm

        res = self.sim.result()
        settings = replace(figure_settings(res.scenario), solver=self._acted(res.steps["mode"]))
        return self._frame(figure_pixels(lambda p: plot_swarm(res.tables, settings, p)))

    def _acted(self, modes) -> str:
        """Who chose the episode's actions, for the figure's title (the steps' ``mode``)."""
        acted = set(np.asarray(modes).tolist())
        if acted <= {"external"}:
            return "external"
        solver = self.sim.c.base.plan.solver
        return f"{solver} and external" if "external" in acted else solver
