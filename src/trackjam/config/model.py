"""The scenario model: every parameter of the paper declared once, typed, with its unit and the
paper's symbol in its description (unknown keys are errors)."""

from __future__ import annotations

import decimal
import math
import numbers
import sys
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    StrictBool,
    field_validator,
    model_serializer,
    model_validator,
)

from trackjam.config.limits import (
    DBW_MAX,
    DBW_MIN,
    MAX_ACCEL_VAR,
    MAX_AGENTS,
    MAX_ANGLE_DEG,
    MAX_SEED,
    MAX_LENGTH,
    MAX_SPEED,
    MAX_STEPS,
    MIN_ANGLE_DEG,
    MIN_EXTENT,
    check_resources,
    check_name,
)
from trackjam.errors import bounded_repr


class LongInteger:
    """An integer literal of more digits than Python converts to an int (4300, its guard against
    quadratic conversions): the YAML reader gives this instead of failing inside the parser, and
    every number of the model refuses it, naming its key."""

    __slots__ = ("digits",)

    def __init__(self, digits: int) -> None:
        self.digits = digits

    def __repr__(self) -> str:
        return f"<an integer of {self.digits} digits>"

    def problem(self) -> str:
        return f"integer too large ({self.digits} digits)"


def _digits(v: int) -> int:
    """Decimal digits of ``v``, without a conversion Python refuses past 4300 digits."""
    try:
        return len(str(abs(v)))
    except ValueError:
        return int(abs(v).bit_length() * math.log10(2)) + 1


def _shown(v: Any) -> str:
    """``v`` for a message: an integer of many digits by its length, not its 4000 digits."""
    if isinstance(v, numbers.Integral) and not isinstance(v, bool) and abs(v) >= 10**20:
        return f"an integer of {_digits(v)} digits"
    return str(v)


def _number(v: Any) -> Any:
    # pydantic's lax mode reads True as 1 and "5" as 5: a value of the wrong kind is a mistake
    if isinstance(v, LongInteger):
        raise ValueError(v.problem())
    if isinstance(v, (bool, str, bytes)):
        raise ValueError(f"must be a number, got {type(v).__name__} {bounded_repr(v)}")
    if isinstance(v, (numbers.Real, decimal.Decimal)):
        # an int of 400 digits or Decimal('NaN') is no finite float (pydantic said "a valid number"
        # and "greater than 0"); float() is what the model keeps anyway
        try:
            f = float(v)
        except OverflowError:
            f = math.inf
        if not math.isfinite(f):
            raise ValueError(f"must be a finite number, got {_shown(v)}")
        return f + 0.0  # -0.0 passes ge=0 yet numpy reads its sign (a scale of -0.0 is "< 0")
    return v


def _integer(v: Any) -> Any:
    if isinstance(v, LongInteger):
        raise ValueError(v.problem())
    if isinstance(v, float) and v.is_integer() and abs(v) < 2**63:
        return int(v)
    if isinstance(v, (bool, str, bytes)) or not isinstance(v, numbers.Integral):
        raise ValueError(f"must be an integer, got {type(v).__name__} {bounded_repr(v)}")
    return int(v)


def Real(ge: float | None = None, le: float | None = None, gt: float | None = None) -> Any:
    """A finite float within bounds (bools and strings refused)."""
    return Annotated[float, BeforeValidator(_number), Field(ge=ge, le=le, gt=gt, allow_inf_nan=False)]


def Integer(ge: int, le: int) -> Any:
    """An integer within bounds (bools, strings and fractions refused)."""
    return Annotated[int, BeforeValidator(_integer), Field(ge=ge, le=le)]


Coord = Real(ge=-MAX_LENGTH, le=MAX_LENGTH)
Length = Real(gt=0, le=MAX_LENGTH)
Speed = Real(ge=-MAX_SPEED, le=MAX_SPEED)
Prob = Real(ge=0, le=1)
DBW = Real(ge=DBW_MIN, le=DBW_MAX)
AccelVar = Real(ge=0, le=MAX_ACCEL_VAR)
Step = Integer(1, MAX_STEPS)
Vec3 = tuple[Coord, Coord, Coord]
# unbounded but finite numbers; a new key should rather say its physical bounds with Real(...)
Finite = Real()
PosFloat = Real(gt=0)
NonNegFloat = Real(ge=0)


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


class Area(_Model):
    """The surveillance box; agents may not leave it, the target is reflected at its walls."""

    low: Vec3 = Field((0.0, 0.0, 0.0), description="lower corner [m], each coordinate within +-1e5")
    high: Vec3 = Field(
        (100.0, 100.0, 100.0), description="upper corner [m], each coordinate within +-1e5 and at least 1 m above low"
    )

    @model_validator(mode="after")
    def _ordered(self) -> "Area":
        for k in range(3):
            if not self.high[k] - self.low[k] >= MIN_EXTENT:
                raise ValueError(f"high must exceed low by at least {MIN_EXTENT:g} m on every axis")
        return self


class Stochastic(_Model):
    """Bernoulli Markov existence of the truth target (Section III-A table)."""

    birth_prob: Prob = Field(0.02, description="p_b: probability the target is born at a step, in [0, 1]")
    survival_prob: Prob = Field(0.98, description="p_s: probability the target survives a step, in [0, 1]")


class Response(_Model):
    """The target's fail-safe under jamming (ours, beyond the paper)."""

    threshold_db: DBW = Field(-40.0, description=f"received power at the target that jams it [dBW], in [{DBW_MIN:g}, {DBW_MAX:g}]")
    steps: Step = Field(3, description=f"consecutive jammed steps before the fail-safe, in [1, {MAX_STEPS}]")
    action: Literal["land", "hover", "return"] = Field("land", description="fail-safe behaviour: `land`, `hover` or `return` (to `home`)")
    speed: Real(gt=0, le=MAX_SPEED) = Field(2.0, description=f"speed while landing or returning [m/step], in (0, {MAX_SPEED:g}]")
    home: Vec3 | None = Field(
        None, description="home point for `return` [m], coordinates within +-1e5; default: area's low corner at z=0"
    )


class ExpectedResponse(Response):
    """The fail-safe the filters expect (``filter.response``, ours): the target's fields and a hedge."""

    hedge: Prob = Field(
        0.0, description="share of a downed track's particles that keep flying at constant velocity, drawn at the "
        "downing, in [0, 1]; 0: all of them take the fail-safe",
    )


class Target(_Model):
    """The truth target (Section III-A)."""

    initial: tuple[Coord, Coord, Coord, Speed, Speed, Speed] | None = Field(
        (20.0, 20.0, 20.0, 1.5, 2.0, 1.7),
        description="x_0 = [x, y, z, vx, vy, vz] [m, m/s], speeds within +-1000 m/s; null: position uniform in "
        "the area, velocity uniform in +-filter.birth_speed",
    )
    appears: Step = Field(1, description=f"scripted existence: first step present, in [1, {MAX_STEPS}] (after the last step: a warning)")
    disappears: Step | None = Field(
        None, description=f"scripted existence: last step present, in [1, {MAX_STEPS}] (null: never)"
    )
    occlusions: list[tuple[Step, Step]] = Field(
        default_factory=list, max_length=1000, description="inclusive step ranges: present but undetectable (at most 1000; past the last step: a warning)"
    )
    accel_var: AccelVar = Field(
        0.5, description=f"Sigma_v = accel_var * I3, acceleration covariance [m^2/s^4], in [0, {MAX_ACCEL_VAR:g}]"
    )
    stochastic: Stochastic | None = Field(None, description="Bernoulli Markov existence instead of the script")
    response: Response | None = Field(None, description="jamming response (ours); null: off, as in the paper")
    walls: Literal["reflect", "leave"] = Field(
        "reflect", description="at the area's walls the target is reflected (`reflect`, ours) or leaves and disappears (`leave`)"
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


MAX_TARGETS = 64
MAX_ID_CHARS = 100


def _target_id(v: Any) -> Any:
    # an id names a target in logs and messages: a whole number or a short text, nothing that
    # reads as something else (True, 2.5)
    if v is None:
        return v
    if isinstance(v, LongInteger):
        raise ValueError(v.problem())
    if isinstance(v, str):
        if not 1 <= len(v) <= MAX_ID_CHARS or v != v.strip():
            raise ValueError(f"a text id must have 1 to {MAX_ID_CHARS} characters and no surrounding blanks, got {bounded_repr(v)}")
        if not v.isprintable():  # a NUL merged two targets in targets.parquet
            raise ValueError(f"a text id must not hold control or other non-printing characters (NUL, a line "
                             f"break, a tab, U+2028), got {bounded_repr(v)}")
        return v
    if isinstance(v, float) and v.is_integer() and abs(v) < 2**63:
        return int(v)
    if isinstance(v, bool) or not isinstance(v, numbers.Integral):
        raise ValueError(f"an id is an integer or a text, got {type(v).__name__} {bounded_repr(v)}")
    if not abs(v) < 2**63:
        raise ValueError(f"an integer id must lie within +-(2^63 - 1), got {_shown(v)}")
    return int(v)


class ListedTarget(Target):
    """One target of ``targets`` (ours): the fields of ``target`` and an id."""

    id: Annotated[int | str | None, BeforeValidator(_target_id)] = Field(
        None,
        description=f"the target's id, an integer within +-(2^63 - 1) or a text of 1 to {MAX_ID_CHARS} characters "
        "without control or other non-printing characters, "
        "unique in the list (1 and '1' are the same id); null: its index in the list",
    )


class Agents(_Model):
    """The pursuers and their admissible moves (Eq. 3)."""

    initial: list[Vec3] = Field(
        [(30.0, 30.0, 30.0), (20.0, 10.0, 10.0), (10.0, 15.0, 15.0)],
        min_length=1,
        max_length=MAX_AGENTS,
        description=f"u_0^j, initial agent positions [m]; N = their number, 1 to {MAX_AGENTS} (two at one place: a warning)",
    )
    initial_aim: Vec3 | None = Field(
        None, description="where the antennas point at t=0 [m], coordinates within +-1e5; default: target's initial position"
    )
    radial_steps: list[Real(gt=0, le=1e4)] = Field(
        [1.0, 3.0, 5.0], min_length=1, max_length=32, description="Delta_R, radial step sizes [m], each in (0, 1e4], at most 32"
    )
    n_inclination: Integer(1, 360) = Field(8, description="N_phi; inclination step is 2*pi/N_phi (docs/model.md), in [1, 360]")
    n_azimuth: Integer(1, 360) = Field(8, description="N_theta; azimuth step is 2*pi/N_theta, in [1, 360]")


def _parse_level(v: Any) -> float | None:
    if v is None or (isinstance(v, str) and v.strip().lower() == "off") or v is False:
        return None
    if isinstance(v, bool):
        raise ValueError("a power level is a number in dBW or 'off'")
    if isinstance(v, LongInteger):
        raise ValueError(f"power level: {v.problem()}")
    if isinstance(v, str):
        try:
            v = float(v)
        except ValueError:
            raise ValueError(f"power level {bounded_repr(v)} is neither a number in dBW nor 'off'") from None
    if not isinstance(v, (int, float)) or (isinstance(v, float) and not math.isfinite(v)):
        raise ValueError(f"power level {bounded_repr(v)} must be a finite number in dBW or 'off'")
    if not DBW_MIN <= v <= DBW_MAX:  # an int compares exactly: math.isfinite(10**400) overflowed
        shown = _shown(v) if isinstance(v, int) else f"{v:g}"
        raise ValueError(f"power level {shown} dBW lies outside [{DBW_MIN:g}, {DBW_MAX:g}] dBW")
    return float(v)


class Antenna(_Model):
    """The conic directional antenna that detects and jams (Eqs. 9-10, 13)."""

    height: Length = Field(40.0, description=f"h_a, cone height along its axis [m], in (0, {MAX_LENGTH:g}]")
    opening_angle_deg: Real() = Field(
        80.0,
        description=f"theta_a, full opening angle of the cone [deg], in [{MIN_ANGLE_DEG:g}, {MAX_ANGLE_DEG:g}] "
        "(a wider cone reaches past any area; below 5 a warning: radians by mistake?)",
    )
    r0: Length = Field(6.0, description=f"R_0, radius of full gain [m], in (0, {MAX_LENGTH:g}]")
    path_loss_exponent: Real(gt=0, le=10) = Field(2.0, description="n_e, path-loss exponent, in (0, 10]")
    p_d_max: Prob = Field(0.95, description="p_D^max, detection probability at full power within R_0, in [0, 1]")
    power_levels_db: list[Any] = Field(
        ["off", -50.0, -7.0, 0.5],
        min_length=1,
        max_length=33,
        description=f"L, transmit levels [dBW], each in [{DBW_MIN:g}, {DBW_MAX:g}]; 'off' is 0 W; at most 32 on",
    )
    interference_limit_db: DBW = Field(
        -40.0, description=f"delta, interference tolerance of every agent [dBW], in [{DBW_MIN:g}, {DBW_MAX:g}]"
    )
    pointing: Literal["truth", "aim"] = Field("truth", description="where the antenna points while transmitting: `truth` (the paper, Sec. IV-C) or `aim` (ours: the planning aim x_bar)")

    @field_validator("opening_angle_deg")
    @classmethod
    def _angle(cls, v: float) -> float:
        if not MIN_ANGLE_DEG <= v <= MAX_ANGLE_DEG:
            raise ValueError(f"opening angle must be in [{MIN_ANGLE_DEG:g}, {MAX_ANGLE_DEG:g}] deg, got {v!r}")
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

    noise_std: tuple[Real(ge=1e-3, le=1e4), Real(ge=1e-6, le=math.pi), Real(ge=1e-6, le=math.pi)] = Field(
        (0.8, math.pi / 50, math.pi / 50),
        description="Sigma_w diagonal as standard deviations: [rho m in [1e-3, 1e4], azimuth rad and inclination "
        "rad in [1e-6, pi]]",
    )
    clutter_rate: Real(ge=0, le=1000) = Field(3.0, description="lambda_c, mean clutter points per agent per step, in [0, 1000]")


class Cue(_Model):
    """A prior the team starts from (ours): where the antennas first point, e.g. from a ground radar."""

    existence: Prob = Field(0.9, description="e_0, initial existence probability of every filter, in [0, 1]")
    position_std: Length = Field(
        2.0, description=f"standard deviation of the initial position around agents.initial_aim [m], in (0, {MAX_LENGTH:g}]"
    )
    velocity_std: Real(gt=0, le=MAX_SPEED) = Field(
        2.0, description=f"standard deviation of the initial velocity around its mean [m/s], in (0, {MAX_SPEED:g}]"
    )
    velocity: Literal["zero", "target"] = Field(
        "zero",
        description="mean of the initial velocity (ours): `zero` (at rest) or `target` (the target's velocity when it "
                    "first appears, as a tracking radar's cue gives a velocity with the position)",
    )


class Visibility(_Model):
    """A hidden-target mode of the filter (ours): the target can be out of sight of every sensor
    (behind an obstacle) while it exists, a two-state Markov chain per step."""

    hide: Prob = Field(description="probability per step that a visible target becomes hidden, in [0, 1]")
    reappear: Prob = Field(description="probability per step that a hidden target becomes visible again, in [0, 1]")
    per_particle: StrictBool = Field(
        False, description="each particle carries its own P(visible), so a place the scans keep missing is believed "
                           "hidden there rather than emptied (ours); false: one P(visible) for the whole filter")


class Mode(_Model):
    """The filter's point estimate at the mode of its density (ours)."""

    radius: Length = Field(
        5.0, description=f"the estimate is the moments of the particles within this of the densest point [m], "
                         f"in (0, {MAX_LENGTH:g}]",
    )
    mass: Real(gt=0, le=1) = Field(
        0.2, description="the least share of the density's weight within `radius` for the estimate to be taken there "
                         "(else the mean of all the particles), in (0, 1]",
    )


class Filter(_Model):
    """Each agent's Bernoulli particle filter (Section V-A)."""

    birth_prob: Prob = Field(0.02, description="p_b used by the filter, in [0, 1]")
    survival_prob: Prob = Field(0.98, description="p_s used by the filter, in [0, 1]")
    particles: Integer(10, 10_000_000) = Field(
        10000, description="particles of the surviving density, in [10, 1e7] (and the memory check)"
    )
    birth_particles: Integer(1, 10_000_000) = Field(
        2000, description="particles of the birth density per step, in [1, 1e7] (and the memory check)"
    )
    birth: Literal["uniform", "measurement", "mixed"] = Field(
        "uniform",
        description="birth density b_t: `uniform` in the area (the paper), `measurement` (ours: around the last scan's "
        "measurements) or `mixed` (ours: filter.birth_mix of `measurement`, the rest `uniform`)",
    )
    birth_speed: Real(ge=0, le=MAX_SPEED) = Field(
        3.0,
        description=f"v_b: birth velocity of the uniform birth, uniform in +-v_b per axis [m/s], in [0, {MAX_SPEED:g}]",
    )
    birth_mix: Prob = Field(
        0.5, description="`mixed` birth (ours): share of b_t that is measurement-driven, the rest uniform [1], in [0, 1]"
    )
    measurement_birth_speed: Real(ge=0, le=MAX_SPEED) = Field(
        8.0,
        description=f"measurement-driven birth (ours): velocity uniform in +-this per axis [m/s], in [0, {MAX_SPEED:g}]",
    )
    accel_var: AccelVar | None = Field(
        None, description=f"filter's Sigma_v scale [m^2/s^4], in [0, {MAX_ACCEL_VAR:g}]; null: the target's"
    )
    walls: Literal["reflect", "none"] = Field(
        "reflect",
        description="the filter's motion model at the area's walls: `reflect`, as the truth does (ours), or `none`: "
        "Eq. (1) unbounded, as printed",
    )
    cue: Cue | None = Field(None, description="initial prior around agents.initial_aim (ours); null: e_0 = 0, nothing known")
    visibility: Visibility | None = Field(
        None,
        description="hidden-target mode (ours): {hide, reappear} per-step probabilities; misses are then explained by "
        "a target out of sight as well as by one that died, and the team reports a target while P(exists and visible) > 0.5; "
        "null: the paper's filter, every existing target visible",
    )
    mode: Mode | None = Field(
        None,
        description="point estimate at the mode (ours): {radius, mass}: after each update an agent reports the mean and "
        "covariance of the particles within `radius` of the densest point of its density when they hold at least "
        "`mass` of its weight, else of all of them; null: the mean of all (the paper)",
    )
    reserve_memory: Integer(0, 100) = Field(
        0,
        description="resampling of a new track (ours): a particle whose line one of the last this many scans before "
        "the current one supported (a measurement near it) keeps a place in the slots reserved for supported "
        "particles, so a track seen once and then missed is not thinned to a few copies; in [0, 100]; 0: only the "
        "current scan's support counts",
    )
    velocity_jitter: Real(ge=0, le=MAX_SPEED) = Field(
        0.0,
        description="regularised resampling of a new track (ours): while the particles a scan supported get the "
        "resampling's reserved slots (a new or re-found track), each extra copy of a particle has N(0, this^2) added to "
        f"each velocity component [m/s], in [0, {MAX_SPEED:g}]; 0: plain copies (the paper's resampling)",
    )
    association_misses: StrictBool = Field(
        False,
        description="several targets (ours): the LMB filters' Gibbs association also weighs, for each track, the best "
        "hypothesis with that track's detection missed; false: only the hypotheses the sampler visits, so a track "
        "whose miss it never visits gets an existence of exactly 1 that no later scan of the step lowers (every "
        "committed several-target measurement used false)",
    )
    team_proposals: StrictBool = Field(
        False,
        description="with fusion.share: scans (ours): the births' importance proposals are drawn around every "
        "measurement of the step's scans, the teammates' too, and the part born at the step before is redrawn from b "
        "times all of its scans' factors; false: the agent's own scan only, which under-weighs a teammate's lone "
        "detection and drops the teammates' factors from the redrawn part (every committed measurement used false)",
    )
    response: ExpectedResponse | None = Field(
        None,
        description="the jamming fail-safe the filters expect (ours), the fields of target.response: once the team's "
        "cones have delivered >= `threshold_db` to at least half of a confirmed track's weight for `steps` steps in a row, the "
        "track's particles move as the fail-safe (`action` at `speed`) instead of at constant velocity; null: Eq. (1) "
        "always (the paper)",
    )


class Fusion(_Model):
    """Fusion of the agents' estimates (end of Section V-A)."""

    feedback: StrictBool = Field(True, description="agents take the fused existence and redraw particles from the fused estimate")
    existence: Literal["mean", "evidence"] = Field(
        "mean",
        description="fused existence: `mean` of the agents' e (the paper) or `evidence` (ours: product of the "
        "agents' likelihood ratios on the common prior, as a centralised filter would)",
    )
    search_reseed: Literal["always", "evidence"] = Field(
        "always",
        description="while searching (`control.fallback: search`), an agent's particles are redrawn from the coasted "
        "track `always`, or (ours) not at a step its own scan raised its existence (e_t > e_{t|t-1}): `evidence`",
    )
    share: Literal["posteriors", "scans"] = Field(
        "posteriors",
        description="what agents exchange to fuse: `posteriors` (the paper: covariance intersection of their "
        "estimates) or `scans` (ours: every agent updates its own particles with every scan it received, "
        "a centralised filter on each agent; no Gaussian collapse)",
    )
    report_spread: Length | None = Field(
        None,
        description="the team reports a confirmed track only while its fused position spread, sqrt(trace(C_pos) / 3), "
        f"is at most this [m] (ours; a belief that has spread out is not a located target), in (0, {MAX_LENGTH:g}]; "
        "null: whenever e > 0.5 (the paper)",
    )


class Grasp(_Model):
    """The options of the paper's distributed GRASP (Section V-D)."""

    samples: Integer(1, 100_000_000) = Field(
        10000, description="n_s, GRASP joint samples per iteration, in [1, 1e8] (and the work check)"
    )
    iterations: Integer(1, 1_000_000) = Field(100, description="n_I, GRASP iterations, in [1, 1e6] (and the work check)")
    neighbours: Integer(2, 1000) = Field(
        6, description="GRASP: size of the list of nearest displacements u-, u+ are drawn from (ours), in [2, 1000]"
    )
    threads: Integer(1, 1024) | None = Field(
        None,
        description="threads (1 to 1024) running the agents' GRASP searches side by side (same result for any value); "
        "null: one per agent up to the CPU count, or 1 inside experiment workers",
    )


class Control(_Model):
    """The joint choice of moves and levels (Sections V-B to V-D)."""

    solver: Literal["greedy", "grasp", "exact"] = Field("grasp", description="`greedy` (Eq. 11), `grasp` (the paper, Sec. V-D) or `exact` (ours: the proven optimum of Eqs. 12-13)")
    greedy_aim: Literal["team", "own"] = Field(
        "team",
        description="where `greedy` evaluates each agent's p_D: `team` (ours: the team's x_bar, as the other solvers "
        "do) or `own` (the paper's Eq. 11: the agent's own predicted mean x_tilde^j when its own predicted existence "
        "exceeds 0.5, the team's aim otherwise; each agent applies its own choice). Not with `control.plan_over: "
        "belief`",
    )
    at_least: Integer(1, MAX_AGENTS) = Field(2, description="n of Xi^N_n: at least n of N agents detect, in [1, N]")
    constraints: StrictBool = Field(True, description="enforce the interference constraints, Eq. (13)")
    grasp: Grasp = Field(default_factory=Grasp, description="GRASP's options (Section V-D)")
    time_limit_s: Real(gt=0, le=3600) = Field(
        1.0,
        description="`exact`: wall-time budget of one step's search [s] (ours); when it runs out the best plan "
        "found is used and the solution reports its certified gap to the optimum",
    )
    node_limit: Integer(0, 10**12) = Field(
        0,
        description="`exact`: budget of one search in search nodes (ours); 0: none. Unlike `time_limit_s` it stops "
        "a search at the same plan on any machine under any load: for runs that must repeat exactly, set it and a "
        "`time_limit_s` long enough that the node budget always runs out first",
    )
    plan_over: Literal["point", "belief"] = Field(
        "point",
        description="what Eq. (12)'s Xi is evaluated at: `point` (the paper: x_bar) or `belief` (ours: Xi averaged over "
        "a weighted sample of the predicted density, `control.belief_samples` particles from each believing agent)",
    )
    belief_samples: Integer(1, 256) = Field(
        16, description="`plan_over: belief`: particles each agent draws from its predicted density and sends, in [1, 256]"
    )
    belief_spread: Length | None = Field(
        None,
        description="`plan_over: belief` only while the belief is wide (ours): an agent averages Xi over the belief "
        "on a step at which some prediction it heard has a position spread sqrt(trace(C_pos) / 3) above this [m], "
        f"and evaluates it at x_bar otherwise, in (0, {MAX_LENGTH:g}]; null: over the belief on every step",
    )
    belief_at_least: Integer(1, MAX_AGENTS) | None = Field(
        None,
        description="`plan_over: belief`: n of Xi^N_n on the steps planned over the belief (ours), in [1, N]; with "
        "`belief_spread` those are the steps at which the belief is too wide to report, and 1 makes a searching team "
        "maximise the chance that any agent finds the target; null: `at_least`",
    )
    fallback: Literal["hover", "search"] = Field(
        "hover",
        description="when no agent believes in the target: `hover` (docs/model.md: hover, keep the last aim, highest "
        "levels the constraints allow) or `search` (ours: plan moves and levels with the solver at the last track "
        "coasted by Eq. (1), whose Gaussian also reseeds the filters)",
    )
    lead: Real(ge=0, le=10) = Field(
        0.0,
        description="lambda, aim lead [steps] (ours): plan and point at x_bar + lambda v_bar, v_bar the believers' mean "
        "predicted velocity, in [0, 10]; 0: x_bar, the paper",
    )
    team_objective: Literal["sum", "min"] = Field(
        "sum",
        description="several targets (ours): the team maximises the `sum` over targets of Xi_k (Eq. 12 per target) or "
        "its `min` (no target left alone); one target: Eq. (12) either way",
    )
    horizon: Integer(1, 100) = Field(
        1,
        description="H, intercept horizon [steps] (ours): aim where the target, coasted by Eq. (1), can first be "
        "reached by the nearest agent within H steps, in 1..100; 1: x_bar, the paper",
    )
    close_in: Real(gt=0, le=1) | None = Field(
        None,
        description="tau, a threshold on Xi (ours; no symbol in the paper): when the best plan's value (Xi of "
        "Eq. 12, or its mean over the belief's samples under "
        "`plan_over: belief`) is below this, the team closes in instead: the agents move as the best plan "
        "without Eq. (13) would take them, and transmit at the levels that maximise that value under Eq. "
        "(13) at those positions (the moves by the solver without Eq. (13), the levels by `exact`; with "
        "`exact` the three solves share `control.time_limit_s`), so a team whose every feasible plan is "
        "worth next to nothing does not spread away from the target; the steps log's `closed_in` marks "
        "those steps; in (0, 1]; null: never (the paper). Not with `control.solver: greedy` or "
        "`control.constraints: false`, which plan without Eq. (13) already, nor with several targets",
    )


class Failure(_Model):
    """One agent's failure from a given step on (ours; SMA-NBO's fault patterns)."""

    agent: Integer(0, MAX_AGENTS - 1) = Field(description=f"index of the failing agent, in [0, {MAX_AGENTS - 1}] (and below N)")
    step: Step = Field(description=f"first step of the failure, in [1, {MAX_STEPS}]")
    mode: Literal["publisher", "channel", "breakdown"] = Field(
        description="`publisher`: its messages no longer reach anyone (it still receives and acts); `channel`: it "
        "neither sends nor receives (acts alone on its own filter); `breakdown`: the agent stops (hovers, "
        "transmits nothing, sends and receives nothing)"
    )


class Comms(_Model):
    """The team's message exchange and its faults (ours; the paper assumes every message arrives)."""

    loss: Prob = Field(0.0, description="probability that each message from one agent to another is lost")
    delay_steps: Integer(0, 1000) = Field(0, description="steps a message takes to arrive, in [0, 1000]")
    stale: Literal["drop", "coast"] = Field(
        "coast",
        description="a teammate's posterior or scan that arrives late: `drop` (only its position is kept) or `coast` "
        "(ours: a posterior is predicted by Eq. (1) to the current step and fused with the fresh ones; under "
        "fusion.share: scans a scan updates the filter at its particles retrodicted to the scan's step)",
    )
    failures: list[Failure] = Field(
        default_factory=list, max_length=1000, description="agents that fail at a given step (at most 1000)"
    )


class Metrics(_Model):
    """Tracking error (Section VI) and track quality judged by the truth (ours)."""

    ospa_order: Real(ge=1, le=10) = Field(2.0, description="p of OSPA, in [1, 10]")
    ospa_cutoff: Length = Field(10.0, description=f"c of OSPA [m], in (0, {MAX_LENGTH:g}], with c^p at least the "
                                "smallest normal float")
    gate: Length = Field(
        5.0, description=f"track quality (ours): held = confirmed and within gate of the truth [m], in (0, {MAX_LENGTH:g}]"
    )

    @model_validator(mode="after")
    def _representable(self) -> "Metrics":
        # c^p below the smallest normal float: the OSPA rounded to 0 (one target) or the swarm
        # engine's OSPA refused it at the first step, after validate had said ok
        if self.ospa_cutoff ** self.ospa_order < sys.float_info.min:
            raise ValueError(f"ospa_cutoff^ospa_order = {self.ospa_cutoff:g}^{self.ospa_order:g} is below the "
                             "smallest normal float, so the OSPA would round to 0; use a larger ospa_cutoff")
        return self


class Oracle(_Model):
    """Diagnostic oracles (ours): the team is told what no real team can know, to measure what
    that knowledge is worth (docs/holding.md). Every one is off by default; none is an option
    for a real team."""

    state_before_hiding: StrictBool = Field(
        False, description="after the last step before each occlusion, every agent's particles are redrawn tight "
        "around the target's true state (0.3 m and 0.1 m/s per axis), its existence kept",
    )
    mean_before_hiding: StrictBool = Field(
        False, description="after the last step before each occlusion, every agent's particles are moved by one offset "
        "so that their weighted mean is the target's true state, their spread and shape kept (a filter whose mean "
        "is exact)",
    )
    truth_after_hiding: Integer(0, MAX_STEPS) = Field(
        0, description="on the first k steps after each occlusion the team plans (and with `antenna.pointing: aim` "
        f"points) at the target's true position, at that point rather than over its belief; 0: never, in [0, {MAX_STEPS}]",
    )
    point_after_hiding: Integer(0, MAX_STEPS) = Field(
        0, description="on the first k steps after each occlusion every antenna points at the target's true position "
        f"(as `antenna.pointing: truth`), while the team plans as it would; 0: never, in [0, {MAX_STEPS}]",
    )
    follow_up: Integer(0, MAX_STEPS) = Field(
        0, description="after any agent detects the target on a step after an occlusion, the team plans (and points) "
        f"at its true position on the next k steps; 0: never, in [0, {MAX_STEPS}]",
    )
    empty_hidden_scans: StrictBool = Field(
        False, description="the filters are told that the scans of an occluded step carry no target: they weigh them "
        "as if every antenna were off",
    )


class Scenario(_Model):
    name: str = Field(
        "scenario",
        description="name of the scenario and of its output folder runs/NAME-seedS: 1 to 100 letters, digits, "
        "'_', '-', '+' or '.', starting with a letter or digit",
    )
    steps: Step = Field(30, description=f"number of steps of dT = 1 s, in [1, {MAX_STEPS}]")
    seed: Integer(0, MAX_SEED) = Field(1, description="the one seed every random choice flows from, in [0, 2^63 - 1]")
    area: Area = Field(default_factory=Area)
    target: Target = Field(default_factory=Target)
    targets: list[ListedTarget] | None = Field(
        None,
        description=f"several truth targets (ours), 1 to {MAX_TARGETS}, each with the keys of `target` and an `id`; "
        "null: the one `target` (a scenario gives `target` or `targets`, not both)",
    )
    agents: Agents = Field(default_factory=Agents)
    antenna: Antenna = Field(default_factory=Antenna)
    sensor: Sensor = Field(default_factory=Sensor)
    filter: Filter = Field(default_factory=Filter)
    fusion: Fusion = Field(default_factory=Fusion)
    control: Control = Field(default_factory=Control)
    comms: Comms = Field(default_factory=Comms)
    metrics: Metrics = Field(default_factory=Metrics)
    oracle: Oracle | None = Field(
        None, description="diagnostic oracles (ours): the team is told what no real team knows, to measure what that "
        "knowledge is worth; null: none, as a real team",
    )

    @field_validator("name")
    @classmethod
    def _name(cls, v: str) -> str:
        check_name(v)
        return v

    @field_validator("targets")
    @classmethod
    def _target_list(cls, v: list[ListedTarget] | None) -> list[ListedTarget] | None:
        if v is None:
            return v
        if not v:
            raise ValueError("the list is empty; give at least one target (or leave targets out for the one `target`)")
        if len(v) > MAX_TARGETS:
            raise ValueError(f"{len(v)} targets, at most {MAX_TARGETS}")
        v = [t.model_copy(update={"id": k}) if t.id is None else t for k, t in enumerate(v)]
        first: dict[str, int] = {}
        for k, t in enumerate(v):
            if str(t.id) in first:
                raise ValueError(f"targets[{first[str(t.id)]}] and targets[{k}] have the same id {t.id!r}")
            first[str(t.id)] = k
        return v

    @model_validator(mode="before")
    @classmethod
    def _no_target(cls, data: Any) -> Any:
        # `target: null` beside a list sets the one target aside, e.g. on a preset that gives one
        if isinstance(data, dict) and "target" in data and data["target"] is None and data.get("targets") is not None:
            return {k: v for k, v in data.items() if k != "target"}
        return data

    @model_validator(mode="after")
    def _one_target(self) -> "Scenario":
        if self.targets is None:
            return self
        if "target" in self.model_fields_set:
            raise ValueError(
                "give either `target` (one target) or `targets` (a list of them), not both; `target: null` sets a "
                "given target aside"
            )
        # code that knows one target reads the first of the list (frozen: set once, here)
        self.__dict__["target"] = Target(**self.targets[0].model_dump(exclude={"id"}))
        return self

    @model_serializer(mode="wrap")
    def _written(self, handler: Any) -> dict:
        # a scenario is written as it is given: `target` for one target, `targets` for a list
        out = handler(self)
        out.pop("target" if self.targets is not None else "targets", None)
        return out

    @model_validator(mode="after")
    def _consistent(self) -> "Scenario":
        n = len(self.agents.initial)
        if self.control.at_least > n:
            raise ValueError(f"control.at_least ({self.control.at_least}) exceeds the number of agents in agents.initial ({n})")
        if self.control.belief_at_least is not None and self.control.belief_at_least > n:
            raise ValueError(f"control.belief_at_least ({self.control.belief_at_least}) exceeds the number of agents in "
                             f"agents.initial ({n})")
        c = self.control
        if c.close_in is not None and (c.solver == "greedy" or not c.constraints):
            why = "control.solver `greedy` plans" if c.solver == "greedy" else "control.constraints `false` plans"
            raise ValueError(f"control.close_in ({c.close_in:g}): {why} without Eq. (13) already, so there is nothing "
                             "to close in from; leave control.close_in null")
        if c.greedy_aim == "own" and c.plan_over == "belief":
            # "leave ... `point`" read oddly where a preset (pursuit) had set `belief`
            raise ValueError("control.greedy_aim `own` evaluates p_D at each agent's own predicted mean, a point: "
                             "set control.plan_over `point` with it (it is `belief`), or leave control.greedy_aim "
                             "`team`")
        lo, hi = self.area.low, self.area.high
        for j, u in enumerate(self.agents.initial):
            if any(not lo[k] <= u[k] <= hi[k] for k in range(3)):
                raise ValueError(f"agents.initial[{j}] {list(u)} lies outside the `area` {self._box()}")
        for k, f in enumerate(self.comms.failures):
            if f.agent >= n:
                raise ValueError(f"comms.failures[{k}].agent {f.agent} is not an agent index (0..{n - 1} in agents.initial)")
        if self.target.initial is not None and self.targets is None:
            x = self.target.initial
            if any(not lo[k] <= x[k] <= hi[k] for k in range(3)):
                raise ValueError(f"target.initial position {list(x[:3])} lies outside the `area` {self._box()}")
        for j, tg in enumerate(self.targets or []):
            if tg.initial is not None and any(not lo[k] <= tg.initial[k] <= hi[k] for k in range(3)):
                raise ValueError(f"targets[{j}].initial position {list(tg.initial[:3])} (id {tg.id!r}) lies outside the "
                                 f"`area` {self._box()}")
        check_resources(self)
        return self

    def _box(self) -> str:
        """The area as a message shows it: ``[0, 0, 0] to [100, 100, 100]``."""
        return " to ".join("[" + ", ".join(f"{v:g}" for v in corner) + "]" for corner in (self.area.low, self.area.high))

    # Derived quantities used everywhere.
    @property
    def n_agents(self) -> int:
        return len(self.agents.initial)

    @property
    def target_list(self) -> list[ListedTarget]:
        """Every truth target with its id: ``targets``, or the one ``target`` with id 0."""
        if self.targets is not None:
            return list(self.targets)
        return [ListedTarget(**self.target.model_dump(), id=0)]

    @property
    def filter_accel_var(self) -> float:
        """The filter's Sigma_v scale: `filter.accel_var`, or the truth's when that is null."""
        return float(self.target.accel_var if self.filter.accel_var is None else self.filter.accel_var)
