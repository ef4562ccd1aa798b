"""The searcher's reference after an occlusion (ours): how soon agents that could stand and aim
anywhere would detect the target again, knowing as much as a team could when it vanished.

The team loses the Fig. 3 target at the occlusion and must find it again. How well could any
team search? This searcher is given every advantage a real team lacks but the one that matters,
where the target is:

- its agents are not bound by their moves: before each step they are put wherever they serve
  best, each with its antenna aimed anywhere, at the top power level, with no interference limit
  (with ``positions`` and ``reach`` they start where the team's agents stood and move at most
  ``reach`` a step, as the agents can);
- it knows when the occlusion ends and searches only on the steps the target can be detected
  (``knows_hidden=False`` takes that away, and ``aims_free=False`` aims every antenna at its
  belief's mean, as a team's under ``antenna.pointing: aim``);
- its belief is exact Bayes for what it is told at the last step before the occlusion: a state
  drawn from N(truth, diag(sd_p^2 I3, sd_v^2 I3)) with that covariance (``sd = (0, 0)``: the true
  state), moved by Eq. (1) and the walls, and weighed after each step by the chance that every
  agent missed.

At each searched step it places its agents to make P(at least one detects the target) under its
belief large (:func:`place`: a local search from two starts, the last step's placement moved with
the belief and a fresh one around it), then draws whether some agent detected the true target;
the first detection ends the search. It is greedy, one step at a time, and the placement is a
local search, not a proven optimum: a reference, like the chaser of ``ceiling.py``, not a proof.
``docs/search_ceiling.py`` runs it on the preset's truths beside the team.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from trackjam.estimation.kernels import kernel_cv_predict, kernel_reflect
from trackjam.radio.antenna import AntennaModel, detection_probability

#: the fresh start's agents stand this far from the belief's mean, each along one axis [m]
#: (at about 10 m a cone aimed at a belief a few metres wide covers the most of it)
FRESH_STANDOFF = 10.0


@dataclass(frozen=True)
class Search:
    first: int | None  # the first step at which some agent detected the target; None: none by the last step
    searched: np.ndarray  # (K,) the steps searched, in order, up to the first detection
    chance: np.ndarray  # (K,) on each, P(some agent detects the target) under the searcher's belief
    truth_chance: np.ndarray  # (K,) on each, P(some agent detects the target) at its true position


def miss_probability(P: np.ndarray, U: np.ndarray, A: np.ndarray, ant: AntennaModel) -> np.ndarray:
    """(n,) the chance that every agent misses a target at each point of ``P`` (n, 3), agent j at
    ``U[j]`` with its antenna aimed at ``A[j]``, at the top power level (Eq. 9)."""
    miss = np.ones(len(P))
    for u, a in zip(U, A):
        if np.allclose(u, a):  # no axis: the antenna points nowhere
            continue
        miss *= 1.0 - detection_probability(P, u, a, ant.l_max, ant)
    return miss


def fresh_placement(center: np.ndarray, n_agents: int) -> tuple[np.ndarray, np.ndarray]:
    """Agents ``FRESH_STANDOFF`` m from ``center`` along +x, +y, +z, -x, ... in turn, each aimed at it."""
    axes = np.vstack([np.eye(3), -np.eye(3)])
    U = center + FRESH_STANDOFF * axes[np.arange(n_agents) % 6]
    return U, np.tile(center, (n_agents, 1))


def within(u: np.ndarray, origin: np.ndarray, r: float) -> np.ndarray:
    """``u`` moved back along the line to ``origin`` until it is at most ``r`` from it."""
    d = float(np.linalg.norm(u - origin))
    return u if d <= r else origin + (u - origin) * (r / d)


def place(P: np.ndarray, w: np.ndarray, starts: list[tuple[np.ndarray, np.ndarray]], ant: AntennaModel,
          rng: np.random.Generator, iterations: int = 150, step: float = 4.0,
          keep: Callable[[int, np.ndarray], np.ndarray] | None = None, aims_free: bool = True
          ) -> tuple[np.ndarray, np.ndarray, float]:
    """Positions (N, 3), aims (N, 3) and value of a placement that makes P(at least one agent
    detects) = sum_i w_i (1 - miss(P_i)) large over the weighted points ``P`` (n, 3), ``w`` (n,)
    summing to 1. From each start, ``iterations`` moves of one agent's position and aim by
    N(0, s^2) per axis are kept when they raise the value, s falling from ``step`` by 1.6 every
    50 moves (to 0.3 m at least); the best of the starts is returned. With ``keep``, agent j's
    proposed position u becomes ``keep(j, u)`` (where its moves can take it). Without
    ``aims_free`` the aims stay those of the start (every antenna at one point, as a team's
    under ``antenna.pointing: aim``)."""
    best = (None, None, -np.inf)
    for U0, A0 in starts:
        U, A = np.array(U0, dtype=float), np.array(A0, dtype=float)
        v = float(w @ (1.0 - miss_probability(P, U, A, ant)))
        s = step
        for it in range(iterations):
            j = int(rng.integers(len(U)))
            U2, A2 = U.copy(), A.copy()
            U2[j] += rng.normal(0.0, s, 3)
            if aims_free:
                A2[j] += rng.normal(0.0, s, 3)
            if keep is not None:
                U2[j] = keep(j, U2[j])
            v2 = float(w @ (1.0 - miss_probability(P, U2, A2, ant)))
            if v2 > v:
                U, A, v = U2, A2, v2
            if it % 50 == 49:
                s = max(s / 1.6, 0.3)
        if v > best[2]:
            best = (U, A, v)
    return best


def search_after(states: list[np.ndarray | None], detectable: np.ndarray, last_seen: int, ant: AntennaModel,
                 accel_var: float, low, high, rng: np.random.Generator, n_agents: int = 3,
                 sd: tuple[float, float] = (0.0, 0.0), particles: int = 2000, iterations: int = 150,
                 walls: bool = True, positions: np.ndarray | None = None, reach: float | None = None,
                 knows_hidden: bool = True, aims_free: bool = True) -> Search:
    """The searcher on one truth: ``states[t]`` the true state (6,) at step t (None while absent;
    index 0 unused), ``detectable[t]``, ``last_seen`` the last step before the occlusion, at which
    the searcher is told the state to within ``sd`` = (position, velocity) standard deviations per
    axis. It searches every detectable step after ``last_seen`` until some agent detects the
    target or the run ends; Eq. (1) with ``accel_var`` and, with ``walls``, the reflection at the
    box [low, high] move its belief (as they move the truth).

    With ``positions`` (N, 3), the agents' positions at ``last_seen``, and ``reach`` [m], the
    searcher is bound by its moves: every step, hidden or not, each agent moves at most ``reach``
    inside the box, to the placement that makes the chance of a detection at that step largest
    (on a hidden step, as if the target could be seen: it gets ready).

    Two of its advantages can be taken away, to see what each is worth: without
    ``knows_hidden`` it does not know when the target is hidden, so it searches the hidden steps
    too and weighs their misses like any other (as a team must); without ``aims_free`` every
    antenna is aimed at the belief's mean (as under ``antenna.pointing: aim``)."""
    if not 0 < last_seen < len(states) - 1 or states[last_seen] is None:
        raise ValueError(f"last_seen: {last_seen} is not a step with the target present before the run's last")
    if (positions is None) != (reach is None):
        raise ValueError("positions and reach: give both (a searcher bound by its moves) or neither")
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    spread = np.repeat(np.asarray(sd, dtype=float), 3)
    told = states[last_seen] + spread * rng.standard_normal(6)  # what it is told: the truth off by one draw
    X = told + spread * rng.standard_normal((particles, 6))  # ... and its belief: that draw's spread around it
    if walls:
        kernel_reflect(X, low, high)
    w = np.full(particles, 1.0 / particles)
    bound = positions is not None
    if bound:
        U0 = np.asarray(positions, dtype=float)
        n_agents = len(U0)
        previous, center = (U0, np.tile(w @ X[:, :3], (n_agents, 1))), w @ X[:, :3]
    else:
        previous, center = None, None
    searched, chance, truth_chance = [], [], []
    for t in range(last_seen + 1, len(states)):
        kernel_cv_predict(X, rng.standard_normal((particles, 3)), 1.0, float(np.sqrt(accel_var)))
        if walls:
            kernel_reflect(X, low, high)
        visible = bool(detectable[t]) and states[t] is not None
        searching = visible or not knows_hidden  # a step on which it looks, and weighs a miss
        if not searching and not bound:
            continue
        P = X[:, :3]
        mean = w @ P
        on_mean = np.tile(mean, (n_agents, 1))
        if previous is not None:  # the last step's aims, moved with the belief (or all on its mean)
            aims = previous[1] + (mean - center) if aims_free else on_mean
        if bound:
            here = previous[0]
            toward = np.clip([within(mean, u, reach) for u in here], low, high)  # a full move toward the mean
            starts = [(here, aims), (toward, on_mean)]
            U, A, v = place(P, w, starts, ant, rng, iterations,
                            keep=lambda j, u, here=here: np.clip(within(u, here[j], reach), low, high),
                            aims_free=aims_free)
        else:
            starts = [fresh_placement(mean, n_agents)]
            if previous is not None:
                starts.insert(0, (previous[0] + (mean - center), aims))
            U, A, v = place(P, w, starts, ant, rng, iterations, aims_free=aims_free)
        previous, center = (U, A), mean
        if not searching:
            continue
        p_true = 1.0 - float(miss_probability(states[t][None, :3], U, A, ant)[0]) if visible else 0.0
        searched.append(t)
        chance.append(v)
        truth_chance.append(p_true)
        if rng.uniform() < p_true:
            return Search(t, np.array(searched), np.array(chance), np.array(truth_chance))
        w = w * miss_probability(P, U, A, ant)
        total = w.sum()
        w = w / total if total > 0.0 else np.full(particles, 1.0 / particles)
    return Search(None, np.array(searched, dtype=int), np.array(chance), np.array(truth_chance))


def kalman_floor(accel_var: float, fix_sd: float, dt: float = 1.0, steps: int = 500) -> tuple[float, float]:
    """Standard deviations per axis (position, velocity) of a Kalman filter on Eq. (1) at its
    steady state, given one position fix per step with noise ``fix_sd`` per axis: what a team
    whose scans together locate the target to ``fix_sd`` can know of it at best."""
    Phi = np.array([[1.0, dt], [0.0, 1.0]])
    G = np.array([[0.5 * dt * dt], [dt]])
    Q = accel_var * G @ G.T
    H = np.array([[1.0, 0.0]])
    P = np.diag([1e4, 1e4])
    for _ in range(steps):
        P = Phi @ P @ Phi.T + Q
        K = P @ H.T / (H @ P @ H.T + fix_sd**2)
        P = (np.eye(2) - K @ H) @ P
    return float(np.sqrt(P[0, 0])), float(np.sqrt(P[1, 1]))
