"""The one place a :class:`Scenario` is read for a run: it becomes the components and the small
settings objects the step's stages take."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from trackjam.config import Scenario
from trackjam.control.planning import PlanSettings
from trackjam.radio.antenna import AntennaModel
from trackjam.simulation.team import TeamSettings
from trackjam.world.moves import displacement_set


def default_threads(n_agents: int) -> int:
    """One thread per agent's GRASP search, up to the CPU count; 1 where the environment says
    one thread per process (experiment workers set TRACKJAM_THREADS=1)."""
    env = os.environ.get("TRACKJAM_THREADS")
    if env:
        return max(1, int(env))
    return max(1, min(n_agents, os.cpu_count() or 1))


@dataclass(frozen=True)
class Components:
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
    plan: PlanSettings
    team: TeamSettings

    def seed_tree(self) -> tuple[np.random.SeedSequence, list[list[np.random.SeedSequence]], np.random.SeedSequence]:
        """One root seed -> the truth's stream, three streams per agent (filter, sensor, plan) and
        the message exchange's stream (losses)."""
        root = np.random.SeedSequence(self.seed)
        truth_seed, agents_seed, comms_seed = root.spawn(3)
        return truth_seed, [s.spawn(3) for s in agents_seed.spawn(self.n_agents)], comms_seed


def build(s: Scenario) -> Components:
    c = s.control
    return Components(
        seed=s.seed,
        n_agents=s.n_agents,
        initial_positions=np.asarray(s.agents.initial, dtype=float),
        initial_aim=None if s.agents.initial_aim is None else np.asarray(s.agents.initial_aim, dtype=float),
        low=np.asarray(s.area.low, dtype=float),
        high=np.asarray(s.area.high, dtype=float),
        antenna=AntennaModel.from_scenario(s),
        displacements=displacement_set(s.agents.radial_steps, s.agents.n_inclination, s.agents.n_azimuth),
        pointing=s.antenna.pointing,
        noise_std=s.sensor.noise_std,
        clutter_rate=float(s.sensor.clutter_rate),
        ospa_cutoff=float(s.metrics.ospa_cutoff),
        ospa_order=float(s.metrics.ospa_order),
        plan=PlanSettings(
            solver=c.solver, at_least=c.at_least, constraints=c.constraints, samples=c.samples,
            iterations=c.iterations, neighbours=c.neighbours,
            threads=c.threads or default_threads(s.n_agents), fallback=c.fallback,
        ),
        team=TeamSettings(
            existence_rule=s.fusion.existence, feedback=s.fusion.feedback,
            searching=c.fallback == "search", accel_var=s.filter_accel_var,
            loss=float(s.comms.loss), delay_steps=int(s.comms.delay_steps),
            failures=tuple((f.agent, f.step, f.mode) for f in s.comms.failures),
        ),
    )
