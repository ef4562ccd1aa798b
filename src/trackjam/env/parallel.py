"""The PettingZoo ``ParallelEnv`` over the step-wise engine (:class:`trackjam.simulation.engine.Simulation`).

Agents ``agent_0`` .. ``agent_{N-1}`` act together once per step. An action is
``[move, level]``: an index into Eq. (3)'s displacement set (0 = hover) and an index into the
transmit levels L (0 = the lowest, "off" in the paper). A move that would take an agent out of
the area is not admissible (the model document): the agent hovers instead and its info says
``hovered: True``. Observations: :mod:`trackjam.env.observation`; reward:
:mod:`trackjam.env.reward`. An episode terminates when the target is downed (``target.response``)
or has flown out of the area (``target.walls: leave``), and is truncated after ``steps``. Several
targets: :class:`trackjam.env.swarm.SwarmParallelEnv`, this class over the swarm engine, which
overrides the hooks below (engine, spaces, observations, actions, outcome, rendering).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from gymnasium import logger, spaces
from pettingzoo import ParallelEnv

from trackjam.arguments import text_path
from trackjam.control.solve import SOLVERS
from trackjam.errors import ConfigError, bounded_repr
from trackjam.env.observation import global_state, observation_bounds, observe, state_bounds
from trackjam.env.reward import reward_terms, team_reward
from trackjam.files import special_file
from trackjam.simulation.build import figure_settings, is_scenario, solver_allowed, with_seed
from trackjam.simulation.actions import has_bool
from trackjam.simulation.engine import Simulation, StepRecord
from trackjam.world.moves import admissible_moves

if TYPE_CHECKING:  # the scenario is only handed on: simulation/build.py reads it
    from trackjam.simulation.build import Scenario

RENDER_MODES = ("rgb_array", "replay")
MAX_RENDER_SIDE = 4096  # pixels: a render_size frame holds at most 4096 x 4096 x 3 bytes (48 MiB)
MAX_JAM_PENALTY = 1e6
MAX_SEED = 2**63 - 1  # the scenario's seed bound
NOT_STARTED = "not started"
CLOSED = "closed"


def _shown(action) -> str:
    """An action as the message shows it, at most 60 characters: a numpy array as the list it
    holds (``[79, 0]``), a large one by its shape."""
    if isinstance(action, np.ndarray):
        return bounded_repr(action.tolist(), 60) if action.size <= 64 else f"an array of shape {action.shape}"
    return bounded_repr(action, 60)


def checked_action(name: str, action, space: spaces.MultiDiscrete, words: str) -> np.ndarray:
    """Agent ``name``'s ``action`` as an int64 array, or one ValueError naming the agent and the
    value: the shape, an integer dtype (a float, NaN or bool is not an index even when numpy
    would cast it to one), and the space's bounds."""
    try:
        a = np.asarray(action)
    except (ValueError, TypeError, OverflowError):  # ragged nested lists: numpy's own words, no agent
        a = np.asarray(None)
    bad = a.shape != space.nvec.shape or a.dtype.kind not in "iu" or has_bool(action)  # numpy reads True as 1
    if bad or not space.contains(a.astype(space.dtype)):
        raise ValueError(f"{name}: action {_shown(action)} is outside the action space "
                         f"MultiDiscrete({space.nvec.tolist()}) ({words} indices)")
    return a.astype(np.int64)


def checked_render_size(render_size, render_mode) -> tuple[int, int] | None:
    """``render_size`` as (width, height) in pixels, each a whole number in [1, MAX_RENDER_SIDE],
    given only with ``render_mode="rgb_array"`` (the replay is a file, and without a mode
    render() draws nothing); None: the whole figure."""
    if render_size is None:
        return None
    shown = bounded_repr(render_size.tolist() if isinstance(render_size, np.ndarray) else render_size, 60)
    if render_mode != "rgb_array":
        raise ValueError(f"render_size: {shown} given with render_mode={render_mode!r}; it sizes the frames of "
                         "render_mode='rgb_array'")
    ok = isinstance(render_size, (tuple, list, np.ndarray)) and len(render_size) == 2 and all(
        not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, np.integer)) and 1 <= v <= MAX_RENDER_SIDE
        for v in render_size)
    if not ok:
        raise ValueError(f"render_size: expected (width, height), two whole numbers of pixels in [1, "
                         f"{MAX_RENDER_SIDE}], got {shown}")
    return int(render_size[0]), int(render_size[1])


def fitted(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """The (H, W, 3) uint8 frame ``img`` scaled to fit ``size`` = (W, H), its aspect kept, centred
    on white."""
    from PIL import Image

    w, h = size
    scale = min(w / img.shape[1], h / img.shape[0])
    inner = (min(w, max(1, round(img.shape[1] * scale))), min(h, max(1, round(img.shape[0] * scale))))
    small = Image.fromarray(img).resize(inner, Image.Resampling.LANCZOS)
    frame = Image.new("RGB", (w, h), (255, 255, 255))
    frame.paste(small, ((w - inner[0]) // 2, (h - inner[1]) // 2))
    return np.array(frame, dtype=np.uint8)


def _check_replay_path(path) -> None:
    """Refuse, at construction, a ``replay_path`` that ``render()`` could not write."""
    p = Path(text_path("replay_path", path))  # a NUL: render() failed in tempfile
    if p.is_dir():
        raise ValueError(f"replay_path: {p} is a folder, not a file")
    if special_file(p):
        raise ValueError(f"replay_path: {p} is not a regular file (a device or a pipe); render() would replace it")
    if not p.absolute().parent.is_dir():
        raise ValueError(f"replay_path: {p.absolute().parent} is not an existing folder")


def figure_pixels(draw) -> np.ndarray:
    """The pixels of the figure ``draw(path)`` writes (and returns the path of), as an (H, W, 3)
    uint8 array; the file is written in a temporary folder and removed."""
    import tempfile
    from pathlib import Path

    import matplotlib.image

    with tempfile.TemporaryDirectory() as tmp:
        img = matplotlib.image.imread(draw(Path(tmp) / "run.png"))
    return np.round(img[..., :3] * 255).astype(np.uint8)


def hover_outside(moves: np.ndarray, positions: np.ndarray, displacements: np.ndarray, low: np.ndarray,
                  high: np.ndarray) -> np.ndarray:
    """Which agents' moves would leave the area; those moves are set to 0 (hover) in place: the
    model document makes a move out of the area inadmissible."""
    hovered = np.array([
        not admissible_moves(positions[j], displacements[moves[j] : moves[j] + 1], low, high)[0]
        for j in range(len(moves))
    ], dtype=bool)
    moves[hovered] = 0
    return hovered


@dataclass(frozen=True)
class Planned:
    """The action of a solver policy: the engine's own planning decides, inside the step, after
    the round of predictions, exactly where :func:`trackjam.simulate` decides. It lies outside
    the action space; the info dict reports the move and level the solver chose."""

    solver: str

    def __post_init__(self) -> None:
        if not isinstance(self.solver, str):  # Planned(["exact"]) was "unhashable type: 'list'" at the step
            raise TypeError(f"Planned: solver must be a solver's name ({', '.join(SOLVERS)}), "
                            f"got {type(self.solver).__name__} {self.solver!r:.60}")


class TrackjamParallelEnv(ParallelEnv):
    metadata = {"name": "trackjam_v0", "render_modes": list(RENDER_MODES), "render_fps": 1}
    ACTION_WORDS = "[move, level]"

    def __init__(self, scenario: Scenario, jam_penalty: float = 1.0, render_mode: str | None = None,
                 replay_path: str = "replay.html", render_size: tuple[int, int] | None = None) -> None:
        is_scenario(scenario)
        self._check_targets(scenario)
        # a penalty past MAX_JAM_PENALTY times the largest violation (about 1.7e4) overflows the reward to -inf
        if (isinstance(jam_penalty, bool) or not isinstance(jam_penalty, (int, float, np.integer, np.floating))
                or not 0 <= jam_penalty <= MAX_JAM_PENALTY):
            raise ValueError(f"jam_penalty: must be a number in [0, {MAX_JAM_PENALTY:g}], got {jam_penalty!r}")
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode: {render_mode!r} is not one of {', '.join(RENDER_MODES)} (or None)")
        if render_mode == "replay":
            self._check_replay(replay_path)
        self.render_size = checked_render_size(render_size, render_mode)
        self.scenario = scenario
        self.jam_penalty = float(jam_penalty)
        self.render_mode = render_mode
        self.replay_path = replay_path
        self.sim = self._engine(scenario)
        self.possible_agents = [f"agent_{j}" for j in range(len(scenario.agents.initial))]
        self.agents: list[str] = []
        self._index = {name: j for j, name in enumerate(self.possible_agents)}
        self._spaces()
        self._seed: int | None = None
        self._solvers_ok: set[str] = set()
        self._ended: str | None = NOT_STARTED

    # -- what the one-target and the several-target environments do differently ---------------

    def _check_targets(self, scenario: Scenario) -> None:
        if len(scenario.target_list) > 1:  # parallel_env gives the several-target environment
            raise ConfigError(
                f"TrackjamParallelEnv simulates one target; this scenario has {len(scenario.target_list)} "
                "(targets): trackjam.env.parallel_env(scenario) gives the several-target environment (SwarmParallelEnv)"
            )

    def _check_replay(self, path) -> None:
        _check_replay_path(path)

    def _engine(self, scenario: Scenario):
        return Simulation(scenario)

    def _spaces(self) -> None:
        c = self.sim.c
        n_moves, n_levels = len(c.displacements), len(c.antenna.levels_w)
        lo, hi = observation_bounds(c.n_agents, c.low, c.high)
        self.action_spaces = {a: spaces.MultiDiscrete([n_moves, n_levels]) for a in self.possible_agents}
        self.observation_spaces = {a: spaces.Box(lo, hi, dtype=np.float32) for a in self.possible_agents}
        self.state_space = spaces.Box(*state_bounds(c.n_agents, c.low, c.high), dtype=np.float32)

    # -- spaces ----------------------------------------------------------------------------

    def _agent(self, agent: str) -> int:
        try:
            return self._index[agent]
        except (KeyError, TypeError):
            raise ValueError(f"unknown agent {agent!r}; the agents are {', '.join(self.possible_agents)}") from None

    def observation_space(self, agent: str) -> spaces.Box:
        self._agent(agent)
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.MultiDiscrete:
        self._agent(agent)
        return self.action_spaces[agent]

    @property
    def solvers(self) -> dict:
        """The registry of the solvers a ``Planned`` action may name (the one-target solvers)."""
        return SOLVERS

    def check_solver(self, solver: str) -> None:
        """Refuse a solver the scenario's configuration would refuse with ``control.solver`` set
        to it: its settings are checked for the configured solver only, so GRASP's samples and
        iterations, past the work cap, ran for hours under another (and ``control.close_in``
        with greedy was ignored)."""
        if solver not in self.solvers:
            raise ValueError(f"Planned: unknown solver {solver!r}; choose from {', '.join(self.solvers)}")
        if solver == self.scenario.control.solver or solver in self._solvers_ok:
            return
        solver_allowed(self.scenario, solver)
        self._solvers_ok.add(solver)

    # -- episode ---------------------------------------------------------------------------

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        """Start an episode on ``seed`` (same seed, same episode: it is the run of
        :func:`trackjam.simulate` with that seed). Without one, the first episode takes the
        scenario's seed and each later one the previous seed + 1, after 2^63 - 1 the seed 0 (a
        seed past it would write a scenario.yaml that no command takes). ``options`` is accepted
        for the API and not read: the scenario says everything."""
        if seed is None:
            # before the first reset, self.sim runs on the scenario's own seed
            seed = self.sim.c.seed if self._seed is None else (self._seed + 1) % (MAX_SEED + 1)
        elif isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= MAX_SEED:
            raise ValueError(f"reset(seed={bounded_repr(seed, 60)}): the seed must be an integer in [0, 2^63 - 1]")
        if options is not None and not isinstance(options, Mapping):
            raise ValueError(f"reset(options={bounded_repr(options, 60)}): options must be a dict or None "
                             "(it is accepted for the API and not read)")
        self._seed = int(seed)
        self.sim = self._engine(with_seed(self.scenario, self._seed))
        self.agents = list(self.possible_agents)
        self._ended = None
        obs = self._first_observations()
        return obs, {a: {"t": 0, "seed": self._seed, "action_mask": self._action_mask(self._index[a]),
                         **self._reset_info(self._index[a])}
                     for a in self.agents}

    def _first_observations(self) -> dict:
        return self._observations(received=[[] for _ in self.possible_agents])

    def _reset_info(self, j: int) -> dict:
        """Agent j's entries of the reset info beyond the step, seed and action mask."""
        return {}

    def state(self) -> np.ndarray:
        """The global state, for a centralised critic (``trackjam.env.state_layout`` names its
        entries): every agent's position and filter estimate, the true target's state, whether
        it exists and is detectable, and the time. No agent observes it."""
        self._check_state()
        sim = self.sim
        truth = sim.truth
        positions = np.clip(sim.team.positions, sim.c.low, sim.c.high)
        estimates = [a.filter.estimate() for a in sim.team.agents]
        return global_state(positions, estimates, truth.state if truth.exists else None, truth.exists,
                            truth.detectable, sim.t / sim.c.steps)

    def _check_state(self) -> None:
        if self._ended == NOT_STARTED:
            raise RuntimeError("state() before reset(): call reset() to start an episode")
        if self._ended == CLOSED:
            raise RuntimeError("state() after close(): call reset() to start a new episode")

    def _action_mask(self, j: int) -> np.ndarray:
        """Agent j's action mask, MultiDiscrete-style: the moves (``len(displacements)`` entries)
        that keep it inside the area from where it stands, then every level (the interference
        limit of Eq. 13 is left to the reward)."""
        c = self.sim.c
        moves = admissible_moves(self.sim.team.agents[j].position, c.displacements, c.low, c.high)
        return np.concatenate([moves, np.ones(len(c.antenna.levels_w), dtype=bool)])

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        if self._ended == NOT_STARTED:
            raise RuntimeError("step() before reset(): call reset() to start an episode")
        if self._ended == CLOSED:
            raise RuntimeError("step() after close(): call reset() to start a new episode")
        if not self.agents:
            raise RuntimeError(f"step() after the episode ended ({self._ended}); call reset()")
        if not isinstance(actions, Mapping):
            raise ValueError(f"actions: expected a dict {{agent: {self.ACTION_WORDS}}}, got {type(actions).__name__}")
        for name in actions:
            self._agent(name)
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"no action for {missing[0]}: every agent acts at every step")
        planned = [actions[a] for a in self.agents if isinstance(actions[a], Planned)]
        if planned:
            first = planned[0]
            for name in self.agents:  # a solver plans for all: one agent's own action would be dropped
                if not (isinstance(actions[name], Planned) and actions[name].solver == first.solver):
                    raise ValueError(f"{name}: action {_shown(actions[name])} is not {first!r}, which another "
                                     "agent has: a solver plans for the whole team; give every agent the same "
                                     "Planned action")
            record, hovered = self._planned_step(planned), np.zeros(len(self.agents), dtype=bool)
        else:
            record, hovered = self._external_step(actions)
        return self._outcome(record, hovered)

    def _external_step(self, actions: dict) -> tuple[StepRecord, np.ndarray]:
        c = self.sim.c
        moves = np.zeros(len(self.possible_agents), dtype=np.int64)
        levels = np.zeros(len(self.possible_agents), dtype=np.int64)
        for name in self.agents:
            j = self._index[name]
            moves[j], levels[j] = checked_action(name, actions[name], self.action_spaces[name], self.ACTION_WORDS)
        hovered = hover_outside(moves, self.sim.team.positions, c.displacements, c.low, c.high)
        return self.sim.step((moves, levels)), hovered

    def _planned_step(self, planned: list[Planned]) -> StepRecord:
        self._plan_with(self._planned_solver(planned))
        return self.sim.step()

    def _planned_solver(self, planned: list[Planned]) -> str:
        """The one solver every agent's ``Planned`` action names, checked for the scenario."""
        solvers = {p.solver for p in planned}
        if len(planned) != len(self.agents) or len(solvers) != 1:
            raise ValueError("a solver plans for the whole team: give every agent the same Planned action")
        solver = solvers.pop()
        self.check_solver(solver)
        return solver

    def _plan_with(self, solver: str) -> None:
        c = self.sim.c
        if c.plan.solver != solver:  # the engine plans with the settings it was built with
            self.sim.c = replace(c, plan=replace(c.plan, solver=solver))

    def _outcome(self, record: StepRecord, hovered: np.ndarray):
        sim, c = self.sim, self.sim.c
        ag = record.agents
        xi, v = reward_terms(ag["p_d"], ag["interference_w"], c.antenna.delta_w, c.plan.at_least)
        reward = team_reward(xi, v, self.jam_penalty)
        truth = sim.truth
        if truth.downed_at is not None:
            end = f"target downed at step {truth.downed_at}"
        elif truth.gone:
            end = f"target left the area by step {record.t}"
        else:
            end = None
        terminated = end is not None
        truncated = not terminated and sim.done
        if terminated or truncated:
            self._ended = end or f"truncated after {c.steps} steps"
        D = c.displacements
        moves = np.argmin(np.linalg.norm((ag["pos"] - ag["prev"])[:, None, :] - D[None], axis=2), axis=1)
        obs = self._observations(received=[_inbox(sim.team, j) for j in range(len(self.possible_agents))])
        live = list(self.agents)
        infos = {
            a: {
                "t": record.t, "move": int(moves[j]), "level": int(ag["level_index"][j]), "hovered": bool(hovered[j]),
                "p_d": float(ag["p_d"][j]), "interference_w": float(ag["interference_w"][j]),
                "jammed": bool(ag["jammed"][j]), "violation": float(v[j]), "xi": xi, "mode": str(ag["mode"][j]),
                "action_mask": self._action_mask(j),
                **({"end": self._ended} if (terminated or truncated) else {}),
            }
            for a, j in ((a, self._index[a]) for a in live)
        }
        if terminated or truncated:
            self.agents = []
        return (obs, {a: reward for a in live}, {a: terminated for a in live}, {a: truncated for a in live},
                infos)

    def _observations(self, received: list[list]) -> dict:
        sim = self.sim
        n = len(self.possible_agents)
        fraction = sim.t / sim.c.steps
        # the engine keeps an agent in the area up to 1e-9 m (world/moves.py's in_area): a move along a
        # wall from x = 0 lands at x = -4e-16, which float32 keeps and the Box's low bound refused
        low, high = sim.c.low, sim.c.high
        return {
            a: observe(j, np.clip(sim.team.agents[j].position, low, high), sim.team.agents[j].filter.estimate(),
                       received[j], n, fraction)
            for a, j in ((a, self._index[a]) for a in self.possible_agents)
        }

    # -- rendering -------------------------------------------------------------------------

    def render(self):
        """``rgb_array``: the Fig. 3 panels of the episode so far as an (H, W, 3) uint8 array
        (fitted to ``render_size`` when one was given); ``replay``: writes the interactive replay
        to ``replay_path`` and returns that path."""
        if not self._ready_to_render():
            return None
        res = self.sim.result()
        settings = replace(figure_settings(res.scenario), solver=self._acted(res.agents["mode"]))
        if self.render_mode == "replay":
            from trackjam.files import atomic_write
            from trackjam.viz.replay import write_replay

            return atomic_write(self.replay_path, lambda p: write_replay(res.steps, res.agents, settings, p))
        from trackjam.viz.figure import plot_run

        return self._frame(figure_pixels(lambda p: plot_run(res.steps, res.agents, settings, p)))

    def _ready_to_render(self) -> bool:
        """False (with gymnasium's warning) without a render mode; an error after ``close()`` or
        before the first step; else True."""
        if self.render_mode is None:
            modes = " or ".join(f"'{m}'" for m in self.metadata["render_modes"])
            logger.warn(f"render() without a render_mode: pass render_mode={modes}")
            return False
        if self._ended == CLOSED:
            raise RuntimeError("render() after close(): call reset() to start a new episode")
        if self.sim.t == 0:
            raise RuntimeError("render(): nothing to draw before the first step")
        return True

    def _frame(self, img: np.ndarray) -> np.ndarray:
        """The figure's pixels, fitted to ``render_size`` when one was given."""
        return img if self.render_size is None else fitted(img, self.render_size)

    def _acted(self, modes) -> str:
        """Who chose the episode's actions, for the figure's title: the solver that planned
        (``Planned`` may name another than the scenario's ``control.solver``), ``external`` for a
        controller's own actions, or both."""
        acted = set(np.asarray(modes).tolist()) - {"down"}
        if acted and acted <= {"external"}:
            return "external"
        solver = self.sim.c.plan.solver
        return f"{solver} and external" if "external" in acted else solver

    def close(self) -> None:
        """End the episode: the environment holds no outside resource, so this only makes a
        later step() or render() an error until reset() starts a new episode."""
        self.agents = []
        self._ended = CLOSED


def _inbox(team, j: int) -> list:
    """The prediction-round messages of this step agent j received (its own included)."""
    return team.fresh(j)
