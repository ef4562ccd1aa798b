"""One step's cooperative decision problem, Eqs. (12)-(13), precomputed as arrays.

Every agent i may move to a *candidate* position u_i + Delta (Delta from the displacement set of
Eq. (3), kept only when it stays inside the area; hover, control 0, is always candidate 0) and
transmit at a level l from L. In planning every candidate's cone aims at the planning aim x_bar
(docs/model.md, antenna pointing), so

- ``p_d[i, c, l]`` is Eq. (9)'s p_D(x_bar, u_i^c, l) of agent i at candidate c and level l;
- ``gain[i, j, ci, cj]`` is the path gain g of sender j's cone (apex at its candidate cj, aimed
  at x_bar) evaluated at receiver i's candidate ci, so that the power i receives from j is
  ``levels_w[l_j] * gain[i, j, ci, cj]`` (Eq. 10, the left side of Eq. 13). Zero for i == j.

Candidates are padded to a common count C; ``n_cand[i]`` says how many of agent i's are real,
and ``move[i, c]`` is the index of candidate c in the displacement set (-1 for padding).

Planning over the belief (ours, issue "holding the target"): given S positions x_s drawn from
the target's predicted density with weights w_s (sum 1), the objective of a joint choice is
sum_s w_s Xi^N_n(p_D^1(x_s), ..., p_D^N(x_s)), each p_D^i(x_s) Eq. (9) for agent i at its
candidate and level with its cone still aimed at x_bar; Eq. (13) is unchanged (cones aimed at
x_bar). ``p_d_samples[s, i, c, l]`` tabulates it; without samples (the paper's point objective)
it is None and every solver reads ``p_d`` as the one sample x_bar with weight 1.
``kernel_gain_table`` is the compiled builder of ``gain``; ``gain_table_reference`` is its
numpy twin, held to it by the tests. ``cone_gain_at`` computes the cone gains behind ``p_d`` and
``p_d_samples`` (compiled geometry, numpy's path gain), bit for bit numpy's ``cone_gain``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from trackjam.arguments import corners, points, whole
from trackjam.radio.antenna import AntennaModel, axis_of, cone_gain, kernel_cone_gain, path_gain
from trackjam.world.moves import in_area


@dataclass(frozen=True)
class Problem:
    """The arrays of one planning step (shapes: N agents, C padded candidates, L levels)."""

    positions: np.ndarray  # (N, 3) u_{t-1}^i [m]
    aim: np.ndarray  # (3,) x_bar, the planning aim [m]
    displacements: np.ndarray  # (K, 3) Eq. (3)'s set, hover first [m]
    levels_w: np.ndarray  # (L,) transmit levels [W], increasing, levels_w[0] may be 0 (off)
    delta_w: float  # delta, interference tolerance [W]
    at_least: int  # n of Xi^N_n
    constraints: bool  # enforce Eq. (13)
    n_cand: np.ndarray  # (N,) number of admissible candidates per agent
    move: np.ndarray  # (N, C) displacement index of each candidate, -1 = padding
    cand_pos: np.ndarray  # (N, C, 3) candidate positions [m] (padding repeats hover)
    p_d: np.ndarray  # (N, C, L) Eq. (9) at x_bar; 0 for padding
    gain: np.ndarray  # (N, N, C, C) receiver i at ci, sender j at cj; 0 on i == j and padding
    samples: np.ndarray | None = None  # (S, 3) x_s, positions of the belief [m]; None: the point x_bar
    weights: np.ndarray | None = None  # (S,) w_s, summing to 1
    p_d_samples: np.ndarray | None = None  # (S, N, C, L) Eq. (9) at x_s, cones aimed at x_bar

    @property
    def n_agents(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_levels(self) -> int:
        return int(self.levels_w.shape[0])

    def objective_tables(self) -> tuple[np.ndarray, np.ndarray]:
        """p_D at every sample, (S, N, C, L), and the weights (S,): the solvers' objective is
        sum_s w_s Xi(p_D at x_s); the point objective is the one sample x_bar, weight 1."""
        if self.p_d_samples is None:
            return self.p_d[None], np.ones(1)
        return self.p_d_samples, self.weights

    def guarded(self, n_planned: int) -> "Problem":
        """This problem with its agents from ``n_planned`` on held at hover, adding nothing to
        the objective (p_D = 0 at every sample) but still receivers of Eq. (13)."""
        n_cand = self.n_cand.copy()
        n_cand[n_planned:] = 1
        p_d = self.p_d.copy()
        p_d[n_planned:] = 0.0
        p_s = None
        if self.p_d_samples is not None:
            p_s = self.p_d_samples.copy()
            p_s[:, n_planned:] = 0.0
        return replace(self, n_cand=n_cand, p_d=p_d, p_d_samples=p_s)

    def fixed_at(self, cand) -> "Problem":
        """This problem with every agent i held at its candidate ``cand[i]`` (its one candidate,
        slot 0): only the levels are left to choose (``control.close_in``, ours)."""
        i = np.arange(self.n_agents)
        c = np.asarray(cand, dtype=np.int64)
        p_s = None if self.p_d_samples is None else np.ascontiguousarray(self.p_d_samples[:, i, c][:, :, None, :])
        return replace(
            self, n_cand=np.ones(self.n_agents, dtype=self.n_cand.dtype),
            move=np.ascontiguousarray(self.move[i, c][:, None]),
            cand_pos=np.ascontiguousarray(self.cand_pos[i, c][:, None, :]),
            p_d=np.ascontiguousarray(self.p_d[i, c][:, None, :]),
            gain=np.ascontiguousarray(self.gain[i[:, None], i[None, :], c[:, None], c[None, :]][:, :, None, None]),
            p_d_samples=p_s,
        )

    def slots_of(self, move) -> np.ndarray:
        """The candidate slot of each agent's displacement index ``move[i]`` (a solution's moves)."""
        return np.array([int(np.flatnonzero(self.move[i, :self.n_cand[i]] == m)[0]) for i, m in enumerate(move)],
                        dtype=np.int64)


@dataclass(frozen=True)
class Solution:
    """A joint control: every agent's displacement and level, with its value at x_bar."""

    move: np.ndarray  # (N,) index into the displacement set (0 = hover)
    level: np.ndarray  # (N,) index into antenna.levels_w
    objective: float  # Xi^N_n of this choice at x_bar (averaged over the samples when planning over the belief)
    feasible: bool  # Eq. (13) holds for every agent (reported even when constraints are off)
    optimal: bool = False  # proven optimal (only `exact` proves it, when its budget suffices)
    gap: float = float("nan")  # certified bound on (optimum - objective); 0 when optimal, NaN: no certificate
    nodes: int = 0  # branch-and-bound nodes visited (`exact`)
    closed_in: bool = False  # control.close_in (ours): moves of the plan without Eq. (13), levels chosen under it


@njit(cache=True)
def kernel_gain_table(cand_pos, cand_axis, n_cand, height, tan_half, r0, n_e):
    """``gain[i, j, ci, cj]`` = g of sender j at cj (unit axis ``cand_axis[j, cj]``) seen at
    receiver i's candidate ci; compiled twin of :func:`gain_table_reference`."""
    N, C = cand_pos.shape[0], cand_pos.shape[1]
    gain = np.zeros((N, N, C, C))
    for i in range(N):
        for j in range(N):
            if i == j:
                continue
            for ci in range(n_cand[i]):
                px, py, pz = cand_pos[i, ci, 0], cand_pos[i, ci, 1], cand_pos[i, ci, 2]
                for cj in range(n_cand[j]):
                    gain[i, j, ci, cj] = kernel_cone_gain(
                        px, py, pz,
                        cand_pos[j, cj, 0], cand_pos[j, cj, 1], cand_pos[j, cj, 2],
                        cand_axis[j, cj, 0], cand_axis[j, cj, 1], cand_axis[j, cj, 2],
                        height, tan_half, r0, n_e,
                    )
    return gain


@njit(cache=True)
def kernel_cone_geometry(points, apex, axis, height, tan_half):
    """For every point ``points[s]`` (S, 3) and apex ``apex[i, c]`` (N, C, 3) with unit axis
    ``axis[i, c]``: ``eta[s, i, c]`` = |x_s - u| and ``inside[s, i, c]``, whether x_s lies in
    the cone (:func:`~trackjam.radio.antenna.inside_cone`'s test).

    The operations of ``cone_gain``'s numpy (its sums over the 3 coordinates run left to right,
    as numpy's), so with the path gain applied in numpy, :func:`cone_gain_at` is ``cone_gain``
    bit for bit in a single pass (a belief of 48 samples: 0.1 instead of 1.5 ms)."""
    S, N, C = points.shape[0], apex.shape[0], apex.shape[1]
    eta = np.empty((S, N, C))
    inside = np.empty((S, N, C), dtype=np.bool_)
    tol = 1e-9
    for s in range(S):
        px, py, pz = points[s, 0], points[s, 1], points[s, 2]
        for i in range(N):
            for c in range(C):
                dx = px - apex[i, c, 0]
                dy = py - apex[i, c, 1]
                dz = pz - apex[i, c, 2]
                ax, ay, az = axis[i, c, 0], axis[i, c, 1], axis[i, c, 2]
                eta[s, i, c] = np.sqrt(dx * dx + dy * dy + dz * dz)
                along = dx * ax + dy * ay + dz * az
                rx = dx - along * ax
                ry = dy - along * ay
                rz = dz - along * az
                radial = np.sqrt(rx * rx + ry * ry + rz * rz)
                inside[s, i, c] = (along >= -tol) & (along <= height + tol) & (radial <= along * tan_half + tol)
    return eta, inside


def cone_gain_at(points, apex, axis, antenna: AntennaModel) -> np.ndarray:
    """``cone_gain(points[s], apex[i, c], aim, antenna)`` as (S, N, C), with ``axis`` the unit
    axis of each apex toward its aim (``axis_of(apex, aim)``): eta and the cone test compiled
    (:func:`kernel_cone_geometry`), the path gain by numpy's :func:`path_gain` over the whole
    block, elementwise as ``cone_gain`` applies it."""
    eta, inside = kernel_cone_geometry(np.ascontiguousarray(points, dtype=np.float64),
                                       np.ascontiguousarray(apex), np.ascontiguousarray(axis),
                                       float(antenna.height), antenna.tan_half)
    return np.where(inside, path_gain(eta, antenna.r0, antenna.n_e), 0.0)


def gain_table_reference(cand_pos, n_cand, aim, antenna: AntennaModel) -> np.ndarray:
    """Plain-numpy twin of :func:`kernel_gain_table`, by broadcasting :func:`cone_gain`."""
    N, C = cand_pos.shape[:2]
    receiver = cand_pos[:, None, :, None, :]
    sender = cand_pos[None, :, None, :, :]
    g = cone_gain(receiver, sender, np.broadcast_to(aim, sender.shape), antenna)
    g = np.array(np.broadcast_to(g, (N, N, C, C)))
    valid = np.arange(C)[None, :] < np.asarray(n_cand)[:, None]  # (N, C)
    g *= valid[:, None, :, None] & valid[None, :, None, :]
    g[np.arange(N), np.arange(N)] = 0.0
    return g


def belief_weights(samples, weights) -> tuple[np.ndarray, np.ndarray]:
    """``samples`` as (S, 3) and ``weights`` as (S,) normalised to sum 1 (None: uniform).

    Raises ``ValueError`` on an empty, non-finite or mis-shaped sample, or on negative weights
    or weights summing to 0."""
    x = np.asarray(samples, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or x.shape[0] < 1 or not np.all(np.isfinite(x)):
        raise ValueError(f"belief samples must be finite positions of shape (S, 3) with S >= 1, got shape {x.shape}")
    if weights is None:
        return x, np.full(x.shape[0], 1.0 / x.shape[0])
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (x.shape[0],) or not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
        raise ValueError("belief weights must be S finite values >= 0 with a positive sum")
    return x, w / w.sum()


def build_problem(positions, aim, displacements, antenna: AntennaModel, low, high,
                  at_least: int, constraints: bool, samples=None, weights=None) -> Problem:
    """Precompute one step's problem: candidates inside the area, Eq. (9) and the pair gains.

    ``samples`` (S, 3) and ``weights`` (S,) (None: uniform; normalised to sum 1) make the
    objective the belief average of Xi (module docstring); None keeps Eq. (12) at ``aim``.
    Raises ``ValueError`` (``TypeError`` for a wrong type) naming the argument when an agent
    lies outside the area (hover must be admissible), when ``at_least`` is not in 1..N, on a
    position, aim or displacement that is not finite with 3 coordinates, on corners not finite
    with low < high, or on a bad sample or weight.
    """
    if not isinstance(antenna, AntennaModel):
        raise TypeError(f"antenna: expected an AntennaModel, got {type(antenna).__name__}")
    u = np.atleast_2d(points("positions", positions))
    if u.ndim != 2:
        raise ValueError(f"positions: expected rows of 3 entries, got shape {u.shape}")
    x_bar = points("aim", aim)
    if x_bar.size != 3:
        raise ValueError(f"aim: expected one point of 3 entries, got shape {x_bar.shape}")
    x_bar = x_bar.reshape(3)
    D = points("displacements", displacements, ndim=2)
    lo, hi = corners(low, high, scalars=True)
    N = u.shape[0]
    if isinstance(at_least, (float, np.floating)) and float(at_least).is_integer():
        at_least = int(at_least)  # 2.0 was taken before the checks
    at_least = whole("at_least", at_least, 1, N)
    if not np.all(in_area(u, low, high)):
        raise ValueError(f"positions: every agent must lie inside the area {lo.tolist()} to {hi.tolist()}")
    if len(D) == 0 or np.any(D[0] != 0.0):
        raise ValueError("displacements: control 0 of the displacement set must be hover (0, 0, 0)")
    ok = in_area(u[:, None, :] + D[None], low, high)  # (N, K): admissible_moves of every agent at once
    n_cand = ok.sum(axis=1).astype(np.int64)
    C = int(n_cand.max())
    move = np.full((N, C), -1, dtype=np.int64)
    for i in range(N):
        move[i, : n_cand[i]] = np.flatnonzero(ok[i])
    cand_pos = u[:, None, :] + D[np.maximum(move, 0)]
    valid = move >= 0
    levels_w = np.asarray(antenna.levels_w, dtype=np.float64)
    cand_axis = np.ascontiguousarray(axis_of(cand_pos, np.broadcast_to(x_bar, cand_pos.shape)))
    g_target = cone_gain_at(x_bar[None], cand_pos, cand_axis, antenna)[0]  # cone_gain(x_bar, cand_pos, x_bar)
    p_d = (levels_w / antenna.l_max * antenna.p_d_max)[None, None, :] * (g_target * valid)[:, :, None]
    gain = kernel_gain_table(
        np.ascontiguousarray(cand_pos), cand_axis, n_cand,
        float(antenna.height), antenna.tan_half, float(antenna.r0), float(antenna.n_e),
    )
    belief = {}
    if samples is not None:
        x_s, w = belief_weights(samples, weights)
        g_s = cone_gain_at(x_s, cand_pos, cand_axis, antenna) * valid  # (S, N, C), cones aimed at x_bar
        scale = levels_w / antenna.l_max * antenna.p_d_max
        belief = dict(samples=x_s, weights=w,
                      p_d_samples=np.ascontiguousarray(scale[None, None, None, :] * g_s[..., None]))
    return Problem(
        positions=u, aim=x_bar, displacements=D, levels_w=levels_w, delta_w=float(antenna.delta_w),
        at_least=int(at_least), constraints=bool(constraints), n_cand=n_cand, move=move,
        cand_pos=cand_pos, p_d=np.ascontiguousarray(p_d), gain=gain, **belief,
    )
