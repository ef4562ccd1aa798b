"""The scenario model: every parameter of the paper declared once, typed, with its unit and the
paper's symbol in its description (unknown keys are errors)."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    field_validator,
    model_validator,
)


Finite = Annotated[float, Field(allow_inf_nan=False)]
PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Prob = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]
Vec3 = tuple[Finite, Finite, Finite]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


class Area(_Model):
    """The surveillance box; agents may not leave it, the target is reflected at its walls."""

    low: Vec3 = Field((0.0, 0.0, 0.0), description="lower corner [m]")
    high: Vec3 = Field((100.0, 100.0, 100.0), description="upper corner [m]")

    @model_validator(mode="after")
    def _ordered(self) -> "Area":
        for k in range(3):
            if not self.high[k] > self.low[k]:
                raise ValueError("high must exceed low on every axis")
        return self


class Stochastic(_Model):
    """Bernoulli Markov existence of the truth target (Section III-A table)."""

    birth_prob: Prob = Field(0.02, description="p_b: probability the target is born at a step")
    survival_prob: Prob = Field(0.98, description="p_s: probability the target survives a step")


class Response(_Model):
    """The target's fail-safe under jamming (ours, beyond the paper)."""

    threshold_db: Finite = Field(-40.0, description="received power at the target that jams it [dBW]")
    steps: int = Field(3, ge=1, description="consecutive jammed steps before the fail-safe")
    action: Literal["land", "hover", "return"] = Field("land", description="fail-safe behaviour")
    speed: PosFloat = Field(2.0, description="speed while landing or returning [m/step]")
    home: Vec3 | None = Field(None, description="home point for `return` [m]; default: area's low corner at z=0")


class Target(_Model):
    """The truth target (Section III-A)."""

    initial: tuple[Finite, Finite, Finite, Finite, Finite, Finite] | None = Field(
        (20.0, 20.0, 20.0, 1.5, 2.0, 1.7),
        description="x_0 = [x, y, z, vx, vy, vz] [m, m/s]; null: position uniform in the area, velocity uniform in +-filter.birth_speed",
    )
    appears: int = Field(1, ge=1, description="scripted existence: first step present")
    disappears: int | None = Field(None, ge=1, description="scripted existence: last step present (null: never)")
    occlusions: list[tuple[int, int]] = Field(
        default_factory=list, description="inclusive step ranges: present but undetectable"
    )
    accel_var: NonNegFloat = Field(0.5, description="Sigma_v = accel_var * I3, acceleration covariance [m^2/s^4]")
    stochastic: Stochastic | None = Field(None, description="Bernoulli Markov existence instead of the script")
    response: Response | None = Field(None, description="jamming response (ours); null: off, as in the paper")
    walls: Literal["reflect", "leave"] = Field(
        "reflect", description="at the area's walls the target is reflected (ours) or leaves and disappears"
    )

    @field_validator("occlusions")
    @classmethod
    def _ranges(cls, v: list[tuple[int, int]]) -> list[tuple[int, int]]:
        for a, b in v:
            if a < 1 or b < a:
                raise ValueError(f"occlusion range [{a}, {b}] must satisfy 1 <= first <= last")
        return v

    @model_validator(mode="after")
    def _order(self) -> "Target":
        if self.disappears is not None and self.disappears < self.appears:
            raise ValueError("disappears must be >= appears")
        return self


class Agents(_Model):
    """The pursuers and their admissible moves (Eq. 3)."""

    initial: list[Vec3] = Field(
        [(30.0, 30.0, 30.0), (20.0, 10.0, 10.0), (10.0, 15.0, 15.0)],
        min_length=1,
        description="u_0^j, initial agent positions [m]; N = their number",
    )
    initial_aim: Vec3 | None = Field(None, description="where the antennas point at t=0 [m]; default: target's initial position")
    radial_steps: list[PosFloat] = Field([1.0, 3.0, 5.0], min_length=1, description="Delta_R, radial step sizes [m]")
    n_inclination: int = Field(8, ge=1, description="N_phi; inclination step is 2*pi/N_phi (MODEL.md)")
    n_azimuth: int = Field(8, ge=1, description="N_theta; azimuth step is 2*pi/N_theta")


def _parse_level(v: Any) -> float | None:
    if v is None or (isinstance(v, str) and v.strip().lower() == "off") or v is False:
        return None
    if isinstance(v, bool):
        raise ValueError("a power level is a number in dBW or 'off'")
    if isinstance(v, str):
        try:
            v = float(v)
        except ValueError:
            raise ValueError(f"power level {v!r} is neither a number in dBW nor 'off'") from None
    if not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"power level {v!r} must be a finite number in dBW or 'off'")
    return float(v)


class Antenna(_Model):
    """The conic directional antenna that detects and jams (Eqs. 9-10, 13)."""

    height: PosFloat = Field(40.0, description="h_a, cone height along its axis [m]")
    opening_angle_deg: float = Field(80.0, description="theta_a, full opening angle of the cone [deg], in (0, 180)")
    r0: PosFloat = Field(6.0, description="R_0, radius of full gain [m]")
    path_loss_exponent: PosFloat = Field(2.0, description="n_e, path-loss exponent")
    p_d_max: Prob = Field(0.95, description="p_D^max, detection probability at full power within R_0")
    power_levels_db: list[Any] = Field(
        ["off", -50.0, -7.0, 0.5], min_length=1, description="L, transmit levels [dBW]; 'off' is 0 W"
    )
    interference_limit_db: Finite = Field(-40.0, description="delta, interference tolerance of every agent [dBW]")
    pointing: Literal["truth", "aim"] = Field("truth", description="where the antenna points while transmitting: `truth` (the paper, Sec. IV-C) or `aim` (ours: the planning aim x_bar)")

    @field_validator("opening_angle_deg")
    @classmethod
    def _angle(cls, v: float) -> float:
        if not math.isfinite(v) or not 0 < v < 180:
            raise ValueError(f"opening angle must be in (0, 180) deg, got {v}")
        return v

    @field_validator("power_levels_db")
    @classmethod
    def _levels(cls, v: list[Any]) -> list[Any]:
        parsed = [_parse_level(x) for x in v]
        if parsed[0] is not None or any(p is None for p in parsed[1:]):
            raise ValueError("the first level, and only it, must be off (all-off keeps Eq. (13) feasible)")
        if len(parsed) < 2:
            raise ValueError("at least one power level must be on")
        out = ["off" if p is None else p for p in parsed]
        watts = [0.0 if p is None else 10 ** (p / 10) for p in parsed]
        if any(b <= a for a, b in zip(watts, watts[1:])):
            raise ValueError("power levels must be strictly increasing")
        return out

    @property
    def levels_w(self) -> list[float]:
        return [0.0 if p == "off" else 10 ** (float(p) / 10) for p in self.power_levels_db]

    @property
    def delta_w(self) -> float:
        return 10 ** (self.interference_limit_db / 10)


class Sensor(_Model):
    """The range/azimuth/inclination measurements (Eqs. 6-8)."""

    noise_std: Vec3 = Field(
        (0.8, math.pi / 50, math.pi / 50),
        description="Sigma_w diagonal as standard deviations: [rho m, azimuth rad, inclination rad]",
    )
    clutter_rate: NonNegFloat = Field(3.0, description="lambda_c, mean clutter points per agent per step")

    @field_validator("noise_std")
    @classmethod
    def _positive(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if any(s <= 0 for s in v):
            raise ValueError("noise standard deviations must be > 0")
        return v


class Cue(_Model):
    """A prior the team starts from (ours): where the antennas first point, e.g. from a ground radar."""

    existence: Prob = Field(0.9, description="e_0, initial existence probability of every filter")
    position_std: PosFloat = Field(2.0, description="standard deviation of the initial position around agents.initial_aim [m]")
    velocity_std: PosFloat = Field(2.0, description="standard deviation of the initial velocity around 0 [m/s]")


class Filter(_Model):
    """Each agent's Bernoulli particle filter (Section V-A)."""

    birth_prob: Prob = Field(0.02, description="p_b used by the filter")
    survival_prob: Prob = Field(0.98, description="p_s used by the filter")
    particles: int = Field(10000, ge=10, description="particles of the surviving density")
    birth_particles: int = Field(2000, ge=1, description="particles of the birth density per step")
    birth: Literal["uniform", "measurement"] = Field("uniform", description="birth density b_t: `uniform` in the area (the paper) or `measurement` (ours: around the last scan's measurements)")
    birth_speed: NonNegFloat = Field(3.0, description="v_b: birth velocity uniform in +-v_b per axis [m/s]")
    accel_var: NonNegFloat | None = Field(None, description="filter's Sigma_v scale; null: the target's")
    walls: Literal["reflect", "none"] = Field(
        "reflect",
        description="the filter's motion model at the area's walls: `reflect`, as the truth does (ours), or `none`: "
        "Eq. (1) unbounded, as printed",
    )
    cue: Cue | None = Field(None, description="initial prior around agents.initial_aim (ours); null: e_0 = 0, nothing known")


class Fusion(_Model):
    """Fusion of the agents' estimates (end of Section V-A)."""

    feedback: bool = Field(True, description="agents take the fused existence and redraw particles from the fused estimate")
    existence: Literal["mean", "evidence"] = Field(
        "mean",
        description="fused existence: `mean` of the agents' e (the paper) or `evidence` (ours: product of the "
        "agents' likelihood ratios on the common prior, as a centralised filter would)",
    )


class Control(_Model):
    """The joint choice of moves and levels (Sections V-B to V-D)."""

    solver: Literal["greedy", "grasp", "exact"] = Field("grasp", description="`greedy` (Eq. 11), `grasp` (the paper, Sec. V-D) or `exact` (ours: the proven optimum of Eqs. 12-13)")
    at_least: int = Field(2, ge=1, description="n of Xi^N_n: at least n of N agents detect")
    constraints: bool = Field(True, description="enforce the interference constraints, Eq. (13)")
    samples: int = Field(10000, ge=1, description="n_s, GRASP joint samples per iteration")
    iterations: int = Field(100, ge=1, description="n_I, GRASP iterations")
    neighbours: int = Field(6, ge=2, description="GRASP: size of the list of nearest displacements u-, u+ are drawn from (ours)")
    threads: int | None = Field(
        None,
        ge=1,
        description="threads running the agents' GRASP searches side by side (same result for any value); "
        "null: one per agent up to the CPU count, or 1 inside experiment workers",
    )
    time_limit_s: float = Field(
        1.0,
        gt=0,
        le=3600,
        allow_inf_nan=False,
        description="`exact`: wall-time budget of one step's search [s] (ours); when it runs out the best plan "
        "found is used and the solution reports its certified gap to the optimum",
    )
    fallback: Literal["hover", "search"] = Field(
        "hover",
        description="when no agent believes in the target: `hover` (MODEL.md: hover, keep the last aim, highest "
        "levels the constraints allow) or `search` (ours: plan moves and levels with the solver at the last track "
        "coasted by Eq. (1), whose Gaussian also reseeds the filters)",
    )


class Failure(_Model):
    """One agent's failure from a given step on (ours; SMA-NBO's fault patterns)."""

    agent: int = Field(ge=0, description="index of the failing agent")
    step: int = Field(ge=1, description="first step of the failure")
    mode: Literal["publisher", "channel", "breakdown"] = Field(
        description="`publisher`: its messages no longer reach anyone (it still receives and acts); `channel`: it "
        "neither sends nor receives (acts alone on its own filter); `breakdown`: the agent stops (hovers, "
        "transmits nothing, sends and receives nothing)"
    )


class Comms(_Model):
    """The team's message exchange and its faults (ours; the paper assumes every message arrives)."""

    loss: Prob = Field(0.0, description="probability that each message from one agent to another is lost")
    delay_steps: int = Field(0, ge=0, le=1000, description="steps a message takes to arrive")
    failures: list[Failure] = Field(default_factory=list, description="agents that fail at a given step")


class Metrics(_Model):
    """Tracking error (Section VI) and track quality judged by the truth (ours)."""

    ospa_order: PosFloat = Field(2.0, description="p of OSPA")
    ospa_cutoff: PosFloat = Field(10.0, description="c of OSPA [m]")
    gate: PosFloat = Field(
        5.0, description="track quality (ours): held = confirmed and within gate of the truth [m]"
    )


class Scenario(_Model):
    name: str = Field("scenario", description="name of the scenario")
    steps: int = Field(30, ge=1, description="number of steps of dT = 1 s")
    seed: int = Field(1, ge=0, description="the one seed every random choice flows from")
    area: Area = Field(default_factory=Area)
    target: Target = Field(default_factory=Target)
    agents: Agents = Field(default_factory=Agents)
    antenna: Antenna = Field(default_factory=Antenna)
    sensor: Sensor = Field(default_factory=Sensor)
    filter: Filter = Field(default_factory=Filter)
    fusion: Fusion = Field(default_factory=Fusion)
    control: Control = Field(default_factory=Control)
    comms: Comms = Field(default_factory=Comms)
    metrics: Metrics = Field(default_factory=Metrics)

    @model_validator(mode="after")
    def _consistent(self) -> "Scenario":
        n = len(self.agents.initial)
        if self.control.at_least > n:
            raise ValueError(f"control.at_least ({self.control.at_least}) exceeds the number of agents ({n})")
        lo, hi = self.area.low, self.area.high
        for j, u in enumerate(self.agents.initial):
            if any(not lo[k] <= u[k] <= hi[k] for k in range(3)):
                raise ValueError(f"agents.initial[{j}] {list(u)} lies outside the area")
        for k, f in enumerate(self.comms.failures):
            if f.agent >= n:
                raise ValueError(f"comms.failures[{k}].agent {f.agent} is not an agent index (0..{n - 1})")
        if self.target.initial is not None:
            x = self.target.initial
            if any(not lo[k] <= x[k] <= hi[k] for k in range(3)):
                raise ValueError(f"target.initial position {list(x[:3])} lies outside the area")
        return self

    # Derived quantities used everywhere.
    @property
    def n_agents(self) -> int:
        return len(self.agents.initial)

    @property
    def filter_accel_var(self) -> float:
        """The filter's Sigma_v scale: `filter.accel_var`, or the truth's when that is null."""
        return float(self.target.accel_var if self.filter.accel_var is None else self.filter.accel_var)
