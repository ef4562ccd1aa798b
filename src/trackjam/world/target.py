"""The truth target: constant-velocity motion (Eq. 1), scripted or stochastic existence,
occlusions, reflection at the walls, and the jamming response (ours, off by default)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trackjam.world.motion import cv_step


def reflect(x: np.ndarray, low, high) -> np.ndarray:
    """Fold a state back into the box, flipping the velocity component of each wall crossed."""
    x = np.array(x, dtype=float)
    for k in range(3):
        lo, hi = low[k], high[k]
        span = hi - lo
        for _ in range(8):  # a step crosses a wall at most a few times
            if x[k] < lo:
                x[k] = 2 * lo - x[k]
                x[3 + k] = -x[3 + k]
            elif x[k] > hi:
                x[k] = 2 * hi - x[k]
                x[3 + k] = -x[3 + k]
            else:
                break
        x[k] = min(max(x[k], lo), lo + span)
    return x


@dataclass(frozen=True)
class Response:
    """The fail-safe under jamming (ours): after ``steps`` consecutive steps at or above
    ``threshold_w`` received, ``action`` ("land" | "hover" | "return") at ``speed`` m/step."""

    threshold_w: float
    steps: int
    action: str
    speed: float
    home: np.ndarray  # (3,) where `return` flies to [m]


@dataclass(frozen=True)
class TargetParams:
    """What the truth target needs (Section IV-A and ours)."""

    low: np.ndarray  # (3,) area's lower corner [m]
    high: np.ndarray  # (3,) upper corner [m]
    initial: np.ndarray | None  # x_0 (6,); None: a random draw
    draw_speed: float  # a random draw's velocity is uniform in +-draw_speed per axis [m/s]
    appears: int
    disappears: int | None
    occlusions: tuple[tuple[int, int], ...]
    accel_var: float  # Sigma_v = accel_var I3
    stochastic: tuple[float, float] | None  # (p_b, p_s) of the Bernoulli chain; None: scripted
    response: Response | None
    walls: str  # "reflect" | "leave"


@dataclass
class TruthTarget:
    """The rogue drone as the world sees it. ``step(t)`` advances it to step ``t`` (1-based)."""

    params: TargetParams
    rng: np.random.Generator
    state: np.ndarray | None = None  # None while absent
    exists: bool = False
    detectable: bool = False
    jammed_run: int = 0  # consecutive steps with received power >= the response threshold
    downed_at: int | None = None  # step the fail-safe started
    gone: bool = False  # it flew out of the area (walls: leave); a script does not bring it back
    _pending_initial: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        p = self.params
        self.low, self.high = p.low, p.high
        if p.initial is not None:
            self._pending_initial = np.asarray(p.initial, dtype=float)
        else:
            self._pending_initial = self.draw_birth()

    def draw_birth(self) -> np.ndarray:
        v = self.params.draw_speed
        pos = self.rng.uniform(self.low, self.high)
        vel = self.rng.uniform(-v, v, size=3)
        return np.concatenate([pos, vel])

    # -- existence --------------------------------------------------------------------------
    def _scripted_exists(self, t: int) -> bool:
        tg = self.params
        return t >= tg.appears and (tg.disappears is None or t <= tg.disappears)

    def _occluded(self, t: int) -> bool:
        return any(a <= t <= b for a, b in self.params.occlusions)

    def step(self, t: int) -> None:
        """Advance to step ``t``: existence, then motion (or the fail-safe), then occlusion."""
        tg = self.params
        # Every draw is made at every step so the stream does not depend on the path taken.
        u_exist = self.rng.uniform()
        birth = self.draw_birth()
        moved = cv_step(self.state if self.state is not None else birth, self.rng, tg.accel_var)
        if tg.stochastic is None:
            now = self._scripted_exists(t) and not self.gone
            if now and not self.exists:
                self.state = self._pending_initial.copy() if self._pending_initial is not None else birth
                self._pending_initial = None
            elif now and self.exists:
                self.state = self._move(moved)
            else:
                self.state = None
            self.exists = now
        else:
            if self.exists:
                if u_exist < tg.stochastic[1]:
                    self.state = self._move(moved)
                else:
                    self.exists, self.state = False, None
            else:
                first = self._pending_initial is not None and t >= tg.appears
                if first or (t >= tg.appears and u_exist < tg.stochastic[0]):
                    self.state = self._pending_initial.copy() if first else birth
                    self._pending_initial = None
                    self.exists = True
        if self.exists and self.state is not None and not np.all(
            (self.state[:3] >= self.low - 1e-9) & (self.state[:3] <= self.high + 1e-9)
        ):
            # only with walls == "leave": it has flown out
            self.exists, self.state, self.gone = False, None, True
        self.detectable = self.exists and not self._occluded(t)

    def _move(self, moved: np.ndarray) -> np.ndarray:
        tg = self.params
        if self.downed_at is not None and tg.response is not None:
            return self._fail_safe()
        if tg.walls == "reflect":
            return reflect(moved, self.low, self.high)
        return moved

    def _fail_safe(self) -> np.ndarray:
        r = self.params.response
        x = self.state.copy()
        if r.action == "hover":
            x[3:] = 0.0
            return x
        if r.action == "land":
            goal = np.array([x[0], x[1], self.low[2]])
        else:
            goal = r.home
        d = goal - x[:3]
        dist = np.linalg.norm(d)
        stepv = d if dist <= r.speed else d / dist * r.speed
        x[:3] = x[:3] + stepv
        x[3:] = stepv
        return x

    def apply_jamming(self, t: int, received_w: float) -> None:
        """Record the power the target received at step ``t``; start the fail-safe when the
        response is on and the power stayed >= threshold for the set number of steps."""
        r = self.params.response
        if r is None or not self.exists or self.downed_at is not None:
            return
        if received_w >= r.threshold_w:
            self.jammed_run += 1
        else:
            self.jammed_run = 0
        if self.jammed_run >= r.steps:
            self.downed_at = t

    @property
    def first_state(self) -> np.ndarray | None:
        """The state the target will appear with (None once it has appeared)."""
        return None if self._pending_initial is None else self._pending_initial.copy()

    @property
    def position(self) -> np.ndarray | None:
        return None if self.state is None else self.state[:3]
