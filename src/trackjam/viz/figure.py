"""The figure of one run, after the paper's Fig. 3 (a)-(h), drawn from the run's logs.

Panels: (a) 3D trajectories, (b) transmit level per agent, (c) who jams whom, (d) received
powers in dB (target and interference, with delta), (e) fused existence probability, (f) OSPA,
(g) and (h) the agents with their sensing cones at two steps (:func:`snapshot_steps`), and under
(f) a band (i) with each step's track quality judged by the truth (ours), so that no panel
lets a confirmed track that has slipped off the target pass for a tracked one.
Steps where the target exists but cannot be detected (occlusion) are shaded on every time axis.

The helpers at the top turn the logs into arrays of the paper's quantities and are shared with
:mod:`trackjam.viz.replay`. Agents are shown 1-based ("agent 1" is log row ``agent == 0``), as
in the paper.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from trackjam.errors import counted  # noqa: E402
from trackjam.metrics.track_quality import CLASSES, step_classes  # noqa: E402
from trackjam.radio.antenna import axis_of, interference_matrix  # noqa: E402
from trackjam.viz.settings import FigureSettings, save_figure  # noqa: E402

Columns = Mapping[str, np.ndarray]
CONE_SEGMENTS = 24

# Black, cyan and red are taken by the truth, the estimate and the target's received power.
AGENT_COLOURS = [
    "#1f77b4", "#9467bd", "#ff7f0e", "#2ca02c", "#8c564b", "#e377c2", "#bcbd22", "#7f7f7f",
]
TRUTH_COLOUR = "black"
ESTIMATE_COLOUR = "#00bcd4"
TARGET_POWER_COLOUR = "#d62728"
OCCLUSION_COLOUR = "0.55"
# One colour per track-quality class, in the order of CLASSES.
QUALITY_COLOURS = {
    "held": "#2ca02c", "false_track": "#ff7f0e", "missed": "#d62728", "phantom": "#9467bd", "silent": "0.85",
}
QUALITY_LABELS = {
    "held": "held", "false_track": "false track", "missed": "missed", "phantom": "phantom", "silent": "silent",
}


def agent_colour(j: int) -> str:
    """Colour of agent ``j`` (0-based), the same in the figure and the replay."""
    return AGENT_COLOURS[j % len(AGENT_COLOURS)]


def agent_table(agents: Columns, column: str, T: int, N: int) -> np.ndarray:
    """The per-agent column as a (T, N) array, row t-1, column j, whatever the log's row order."""
    out = np.full((T, N), np.nan)
    t = np.asarray(agents["t"], dtype=int)
    j = np.asarray(agents["agent"], dtype=int)
    out[t - 1, j] = np.asarray(agents[column], dtype=float)
    return out


def agent_positions(agents: Columns, T: int, N: int, prefix: str = "") -> np.ndarray:
    """(T, N, 3) positions: ``prefix=""`` after the move u_t, ``"prev_"`` before it, ``"point_"`` aims."""
    return np.stack([agent_table(agents, f"{prefix}{ax}", T, N) for ax in "xyz"], axis=-1)


def steps_xyz(steps: Columns, prefix: str) -> np.ndarray:
    """(T, 3) of ``truth_``, ``est_`` or ``aim_`` columns (NaN rows where absent)."""
    return np.stack([np.asarray(steps[f"{prefix}{ax}"], dtype=float) for ax in "xyz"], axis=-1)


# the columns of a run's logs the figure and the replay read (``mode`` of the steps, when there)
READ_STEPS = (
    "t", "target_exists", "target_detectable", "truth_x", "truth_y", "truth_z", "existence",
    "est_x", "est_y", "est_z", "ospa", "aim_x", "aim_y", "aim_z", "objective", "target_received_w", "solve_s",
)
READ_AGENTS = (
    "t", "agent", "prev_x", "prev_y", "prev_z", "x", "y", "z", "level_index", "power_w",
    "point_x", "point_y", "point_z", "p_d", "detected", "measurements", "existence",
    "interference_w", "jammed", "to_target_w",
)


def run_shape(steps: Columns, agents: Columns, fs: FigureSettings) -> tuple[int, int]:
    """(T, N): the number of steps and of agents in a run's ``steps`` and ``agents`` logs, or one ValueError (TypeError for a wrong
    type) naming the log and the problem: the columns they read (``READ_STEPS``, ``READ_AGENTS``),
    each one-dimensional and of its log's length, steps 1..T in order, one agents row per step
    and agent, and power levels of the antenna ``fs`` has. Handed odd logs, the figure and the
    replay failed deep in numpy (an empty log), drew a 3-step run with one step of agents, or
    failed on a level index of 99 with an IndexError."""
    if not isinstance(fs, FigureSettings):
        raise TypeError(f"fs: expected the run's FigureSettings (simulation.build.figure_settings), got {type(fs).__name__}")
    lengths = {}
    for name, log, columns in (("steps", steps, READ_STEPS), ("agents", agents, READ_AGENTS)):
        if not isinstance(log, Mapping):
            raise TypeError(f"{name}: expected the run's {name} log (column name -> array), got {type(log).__name__}")
        missing = [c for c in columns if c not in log]
        if missing:
            raise ValueError(f"{name}: not a run's {name} log: missing {', '.join(missing[:4])}"
                             f"{' and more' if len(missing) > 4 else ''}")
        shapes = {np.shape(log[c]) for c in columns}
        if len(shapes) != 1 or len(next(iter(shapes))) != 1:
            raise ValueError(f"{name}: its columns must be one-dimensional and of one length, got shapes {sorted(shapes)}")
        lengths[name] = next(iter(shapes))[0]
    T = lengths["steps"]
    t = np.asarray(steps["t"])
    if T == 0 or not np.array_equal(t, np.arange(1, T + 1)):
        raise ValueError(f"steps: t must run 1, 2, ... with one row per step, got {t[:5].tolist()}{'...' if T > 5 else ''}")
    at, agent = np.asarray(agents["t"]), np.asarray(agents["agent"])
    if lengths["agents"] == 0 or agent.min() < 0:
        raise ValueError("agents: no rows, or a negative agent index")
    N = int(agent.max()) + 1
    if lengths["agents"] != T * N or not np.array_equal(np.sort(at * N + agent), np.arange(N, (T + 1) * N)):
        raise ValueError(f"agents: expected one row per step (1..{T}) and agent (0..{N - 1}), {T * N} rows, "
                         f"got {lengths['agents']} rows")
    level = np.asarray(agents["level_index"])
    if np.any(level < 0) or np.any(level >= len(fs.antenna.levels_w)):
        raise ValueError(f"agents: level_index must lie in 0..{len(fs.antenna.levels_w) - 1}, the antenna's "
                         f"power levels, got {int(level.min())}..{int(level.max())}")
    return T, N


def interference_per_step(agents: Columns, fs: FigureSettings, at: np.ndarray | None = None) -> np.ndarray:
    """(K, N, N) ``R[k, i, j]``: power agent i receives from agent j [W] (Eq. 13's terms) at the
    0-based step indices ``at`` (every step when None, K = T).

    Recomputed with :func:`interference_matrix` from the logged positions after the move, the
    points the antennas aimed at and the transmit powers, so it is what the loop measured.
    """
    u, point, level_w = _transmitters(agents)
    at = np.arange(len(u)) if at is None else np.asarray(at, dtype=int)
    return _interference_at(u, point, level_w, at, fs)


def _transmitters(agents: Columns) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, N, 3) positions after the move, (T, N, 3) aims and (T, N) transmit powers [W]."""
    T = int(np.max(agents["t"]))
    N = int(np.max(agents["agent"])) + 1
    u = agent_positions(agents, T, N)
    point = agent_positions(agents, T, N, "point_")
    level_w = np.nan_to_num(agent_table(agents, "power_w", T, N))
    # An antenna that is off has no meaningful aim: give it one (it sends nothing anyway).
    point = np.where(np.isfinite(point), point, u + np.array([0.0, 0.0, 1.0]))
    return u, point, level_w


def _interference_at(u, point, level_w, at: np.ndarray, fs: FigureSettings) -> np.ndarray:
    N = u.shape[1]
    out = np.empty((len(at), N, N))
    for n, k in enumerate(at):
        out[n] = interference_matrix(u[k], point[k], level_w[k], fs.antenna)
    return out


def jamming_events(agents: Columns, fs: FigureSettings, chunk: int = 1024
                   ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """Where agents were jammed, from :func:`interference_per_step` taken ``chunk`` steps at a
    time (the whole (T, N, N) array is 3.3 GB at 100,000 steps of 64 agents):
    ``(t, i, j)`` of each step t (1-based) at which sender j alone jams receiver i
    (R_ij >= delta), and ``(t, i)`` of each step at which only the sum over senders does."""
    delta = fs.antenna.delta_w
    u, point, level_w = _transmitters(agents)
    T = len(u)
    pair: list[np.ndarray] = []
    only: list[np.ndarray] = []
    for first in range(0, T, chunk):
        R = _interference_at(u, point, level_w, np.arange(first, min(first + chunk, T)), fs)
        hit = R >= delta
        k, i, j = np.nonzero(hit)
        pair.append(np.stack([k + first + 1, i, j]).astype(np.int64))
        k, i = np.nonzero((R.sum(axis=2) >= delta) & ~hit.any(axis=2))
        only.append(np.stack([k + first + 1, i]).astype(np.int64))
    p, o = np.concatenate(pair, axis=1), np.concatenate(only, axis=1)
    return (p[0], p[1], p[2]), (o[0], o[1])


def level_labels(fs: FigureSettings) -> list[str]:
    """Tick labels of the transmit levels L: "off" or "<l> dBW"."""
    return ["off" if p == "off" else f"{float(p):g} dBW" for p in fs.power_levels_db]


def occluded_steps(steps: Columns) -> np.ndarray:
    """Steps where the target exists but nobody can detect it."""
    ex = np.asarray(steps["target_exists"], dtype=bool)
    det = np.asarray(steps["target_detectable"], dtype=bool)
    return np.asarray(steps["t"])[ex & ~det]


def to_db(w: np.ndarray) -> np.ndarray:
    """10 log10(w) in dBW; -inf for 0 W, NaN stays NaN."""
    w = np.asarray(w, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return 10 * np.log10(w)


# --------------------------------------------------------------------------------------------


def cone_mesh(apex: np.ndarray, point: np.ndarray, height: float, half_angle: float,
              segments: int = CONE_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (segments + 2, 3) and triangles (2 * segments, 3) of the closed sensing cone.

    Vertex 0 is the apex, 1..segments the rim at distance h_a along the axis with radius
    h_a tan(theta_a / 2), the last one the centre of the base.
    """
    apex = np.asarray(apex, dtype=float)
    a = axis_of(apex, point)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(a, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    phi = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    centre = apex + height * a
    radius = height * np.tan(half_angle)
    rim = centre + radius * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    vertices = np.vstack([apex, rim, centre])
    k = np.arange(1, segments + 1)
    k_next = np.roll(k, -1)
    side = np.stack([np.zeros(segments, dtype=int), k, k_next], axis=1)
    base = np.stack([np.full(segments, segments + 1), k_next, k], axis=1)
    return vertices, np.vstack([side, base])


def plot_run(steps: Columns, agents: Columns, fs: FigureSettings, path: str | Path) -> Path:
    """Draw panels (a)-(h) of the paper's Fig. 3 for one run and save them as a PNG at ``path``.

    ``steps`` and ``agents`` are the run's logs (column name -> 1-D array), ``fs`` what the run's
    scenario says beside them (:func:`trackjam.simulation.build.figure_settings`). Returns the path.
    """
    T, N = run_shape(steps, agents, fs)
    path = Path(path)
    t = np.asarray(steps["t"], dtype=float)
    fig = plt.figure(figsize=(17, 14), layout="constrained")
    outer = fig.add_gridspec(1, 2, width_ratios=[1.0, 1.15])
    left = outer[0].subgridspec(2, 2, height_ratios=[1.25, 1.0])
    ax3d = fig.add_subplot(left[0, :], projection="3d")
    ax_g = fig.add_subplot(left[1, 0], projection="3d")
    ax_h = fig.add_subplot(left[1, 1], projection="3d")
    right = outer[1].subgridspec(6, 1, height_ratios=[1.1, 1.0, 1.3, 1.0, 1.0, 0.28])
    axes = [fig.add_subplot(right[0])]
    axes += [fig.add_subplot(right[k], sharex=axes[0]) for k in range(1, 6)]
    ax_level, ax_jam, ax_power, ax_exist, ax_ospa, ax_quality = axes

    _panel_trajectories(ax3d, steps, agents, fs, T, N)
    _panel_levels(ax_level, agents, fs, t, T, N)
    _panel_jamming(ax_jam, agents, fs, T, N)
    _panel_powers(ax_power, steps, agents, fs, t, T, N)
    _panel_existence(ax_exist, steps, agents, t, T, N)
    _panel_ospa(ax_ospa, steps, fs, t)
    _panel_quality(ax_quality, steps, fs, t)
    (k_g, why_g), (k_h, why_h) = snapshot_steps(agents, fs, T, N)
    _panel_cones(ax_g, steps, agents, fs, T, N, k_g, f"(g) step {k_g}: {why_g}")
    _panel_cones(ax_h, steps, agents, fs, T, N, k_h, f"(h) step {k_h}: {why_h}")

    occ = _spans(occluded_steps(steps))
    for ax in axes:
        for first, last in occ:
            ax.axvspan(first - 0.5, last + 0.5, color=OCCLUSION_COLOUR, alpha=0.18, lw=0, zorder=0)
        ax.set_xlim(0.5, T + 0.5)
        ax.grid(True, alpha=0.3)
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True, min_n_ticks=1))
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    ax_quality.set_xlabel("time step t  (dT = 1 s)")
    handles, _ = ax_level.get_legend_handles_labels()
    if len(occ):
        handles.append(Patch(color=OCCLUSION_COLOUR, alpha=0.3, label="target occluded"))
    ax_level.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)
    fig.suptitle(f"trackjam run: {fs.name}  ({counted(N, 'agent')}, {counted(T, 'step')}, solver {fs.solver})")
    save_figure(fig, path, format="png")
    plt.close(fig)
    return path


PATH_MARGIN = 0.1  # of the paths' extent, at least MIN_MARGIN_M, around the box of panel (a)
MIN_MARGIN_M = 2.0


def path_box(points: np.ndarray, fs: FigureSettings) -> tuple[np.ndarray, np.ndarray]:
    """Corners of the box panel (a) shows: the finite ``points`` with a margin, inside the area
    (the whole area when there is nothing to show)."""
    area_lo, area_hi = fs.low, fs.high
    p = points[np.isfinite(points).all(axis=1)]
    if not len(p):
        return area_lo, area_hi
    lo, hi = p.min(axis=0), p.max(axis=0)
    margin = np.maximum(PATH_MARGIN * (hi - lo).max(), MIN_MARGIN_M)
    return np.maximum(lo - margin, area_lo), np.minimum(hi + margin, area_hi)


def _panel_trajectories(ax, steps, agents, fs, T, N) -> None:
    """(a) truth (black), fused estimate (cyan), agents u_t (coloured); o = start, ^ = end."""
    truth = steps_xyz(steps, "truth_")
    est = steps_xyz(steps, "est_")
    u = agent_positions(agents, T, N)
    u0 = agent_positions(agents, T, N, "prev_")[0]
    ax.plot(*truth.T, color=TRUTH_COLOUR, lw=2, label="target (truth)")
    ax.plot(*est.T, color=ESTIMATE_COLOUR, lw=1.6, marker=".", ms=5, label="target (fused estimate)")
    first = np.flatnonzero(np.isfinite(truth[:, 0]))
    if len(first):
        ax.scatter(*truth[first[0]], color=TRUTH_COLOUR, marker="*", s=120, depthshade=False)
    for j in range(N):
        path = np.vstack([u0[j], u[:, j]])
        c = agent_colour(j)
        ax.plot(*path.T, color=c, lw=1.6, label=f"agent {j + 1}")
        ax.scatter(*path[0], color=c, marker="o", s=60, edgecolor="k", depthshade=False)
        ax.scatter(*path[-1], color=c, marker="^", s=60, edgecolor="k", depthshade=False)
    lo, hi = path_box(np.vstack([truth, est, u0, u.reshape(-1, 3)]), fs)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]", labelpad=-4)  # nearer its ticks: the zoomed box draws it past the panel
    ax.set_box_aspect(hi - lo, zoom=1.2)
    ax.set_title("(a) trajectories, zoomed to the paths  (o start, ^ end, * target appears)")
    ax.legend(loc="upper left", fontsize=8)


def _panel_levels(ax, agents, fs, t, T, N) -> None:
    """(b) transmit level l_t^j per agent, as an index into L."""
    idx = agent_table(agents, "level_index", T, N)
    offsets = (np.arange(N) - (N - 1) / 2) * min(0.08, 0.4 / max(N, 1))
    for j in range(N):
        ax.step(t, idx[:, j] + offsets[j], where="mid", color=agent_colour(j), lw=1.6,
                marker="o", ms=3.5, label=f"agent {j + 1}")
    labels = level_labels(fs)
    ax.set_yticks(range(len(labels)), labels)
    ax.set_ylim(-0.5, len(labels) - 0.5)
    ax.set_ylabel("transmit level")
    ax.set_title("(b) transmit power level per agent", loc="left", fontsize=10)


def _panel_jamming(ax, agents, fs, T, N) -> None:
    """(c) one row per receiver i: a marker in sender j's colour at steps where j alone jams i
    (R_ij >= delta), a black ring where only the total sum_j R_ij >= delta does."""
    (pair_t, pair_i, pair_j), (only_t, only_i) = jamming_events(agents, fs)
    spread = min(0.3, 0.6 / max(N - 1, 1))
    for i in range(N):
        ax.axhline(i, color="0.85", lw=0.8, zorder=0)
        senders = [j for j in range(N) if j != i]
        for k, j in enumerate(senders):
            dy = (k - (len(senders) - 1) / 2) * spread / 2
            hit = pair_t[(pair_i == i) & (pair_j == j)]
            ax.scatter(hit, np.full(len(hit), i + dy), color=agent_colour(j), marker="s", s=28,
                       edgecolor="k", lw=0.4, zorder=3)
        only_sum = only_t[only_i == i]
        ax.scatter(only_sum, np.full(len(only_sum), i), facecolor="none", edgecolor="k",
                   marker="o", s=60, lw=1.2, zorder=3)
    ax.set_yticks(range(N), [f"agent {i + 1}" for i in range(N)])
    ax.set_ylim(N - 0.5, -0.5)
    ax.set_ylabel("jammed agent")
    ax.set_title("(c) who jams whom (row: receiver; colour: sender)", loc="left", fontsize=10)
    handles = [Line2D([], [], ls="", marker="s", color=agent_colour(j), mec="k", mew=0.4,
                      label=f"by agent {j + 1}") for j in range(N)]
    handles.append(Line2D([], [], ls="", marker="o", mfc="none", mec="k", label="by the sum only"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)


def _panel_powers(ax, steps, agents, fs, t, T, N) -> None:
    """(d) power received at the target (Eq. 10, summed over agents) and interference at each
    agent, in dBW. 0 W has no decibel value: the target's line has a gap there, and a row of
    markers under the axis' finite range ("0 W") says which steps had no power."""
    delta_db = fs.interference_limit_db
    target_db = to_db(steps["target_received_w"])
    interf_db = to_db(agent_table(agents, "interference_w", T, N))
    finite = np.concatenate([target_db[np.isfinite(target_db)], interf_db[np.isfinite(interf_db)], [delta_db]])
    floor = 10 * np.floor((finite.min() - 5) / 10)
    top = 10 * np.ceil((finite.max() + 3) / 10)

    none = np.isneginf(target_db)
    ax.plot(t, np.where(none, np.nan, target_db), color=TARGET_POWER_COLOUR, lw=2, marker=".", label="at the target")
    if none.any():
        ax.scatter(t[none], np.full(none.sum(), floor), color=TARGET_POWER_COLOUR, marker="v", s=45,
                   zorder=4, label="no power at the target")  # above the agents' open circles
    offsets = (np.arange(N) - (N - 1) / 2) * 0.12
    for j in range(N):
        ax.scatter(t + offsets[j], np.where(np.isneginf(interf_db[:, j]), floor, interf_db[:, j]),
                   facecolor="none", edgecolor=agent_colour(j), lw=1.4, s=36,
                   label=f"interference at agent {j + 1}")
    ax.axhline(delta_db, color="k", ls="--", lw=1, label=f"delta = {delta_db:g} dBW")
    ax.set_ylim(floor - 2, top)
    ticks = [v for v in ax.get_yticks() if floor + 0.1 * (top - floor) < v <= top]
    ax.set_yticks([floor, *ticks], ["0 W", *[f"{v:g}" for v in ticks]])
    ax.set_ylabel("received power [dBW]")
    ax.set_title("(d) received power: target (line) and agents' interference (circles)", loc="left", fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)


def _spans(ks) -> list[tuple[int, int]]:
    """The runs of consecutive steps in ``ks`` (sorted) as (first, last): one shaded span each,
    where a span per step had made a 100,000-step figure take minutes and gigabytes."""
    ks = np.asarray(ks, dtype=np.int64).ravel()
    if ks.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(ks) != 1)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks, [ks.size - 1]])
    return [(int(ks[a]), int(ks[b])) for a, b in zip(starts, ends)]


def _panel_existence(ax, steps, agents, t, T, N) -> None:
    """(e) fused existence probability (mean of the agents' e, Section V-A) and the truth."""
    exists = np.asarray(steps["target_exists"], dtype=bool)
    for first, last in _spans(t[exists]):
        ax.axvspan(first - 0.5, last + 0.5, color="#2ca02c", alpha=0.12, lw=0, zorder=0)
    own = agent_table(agents, "existence", T, N)
    for j in range(N):
        ax.plot(t, own[:, j], color=agent_colour(j), lw=0.8, alpha=0.6)
    fused = np.asarray(steps["existence"], dtype=float)
    ax.plot(t, fused, color=TARGET_POWER_COLOUR, lw=2, marker=".", label="fused existence")
    # the steps the team reported: above 0.5 is not the report rule under filter.visibility or
    # fusion.report_spread, and a line labelled "target reported" had said so
    reported = np.isfinite(np.asarray(steps["est_x"], dtype=float))
    ax.plot(t[reported], fused[reported], ls="none", marker="o", ms=6, mfc="none", mec="k", mew=1.0,
            label="reported")
    ax.axhline(0.5, color="k", ls="--", lw=1, label="0.5")
    ax.set_ylim(-0.03, 1.03)
    ax.set_ylabel("P(target exists)")
    ax.set_title("(e) existence probability (thin: each agent's own)", loc="left", fontsize=10)
    handles, _ = ax.get_legend_handles_labels()
    handles.append(Patch(color="#2ca02c", alpha=0.25, label="target exists (truth)"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)


def _panel_ospa(ax, steps, fs, t) -> None:
    """(f) OSPA(p, c) between the truth set and the reported estimate set."""
    p, c = fs.ospa_order, fs.ospa_cutoff
    ax.plot(t, np.asarray(steps["ospa"], dtype=float), color="k", lw=1.6, marker=".", label="OSPA")
    ax.axhline(c, color="0.4", ls=":", lw=1, label=f"cut-off c = {c:g} m")
    ax.set_ylim(-0.03 * c, 1.1 * c)
    ax.set_ylabel("OSPA [m]")
    ax.set_title(f"(f) tracking error OSPA(p={p:g}, c={c:g} m)", loc="left", fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)


def _panel_quality(ax, steps, fs, t) -> None:
    """Track quality judged by the truth, one coloured cell per step (README, "Track quality
    judged by the truth"): held (confirmed, within metrics.gate of the truth), false track
    (confirmed, further off), missed (detectable, not confirmed), phantom (confirmed while the
    target is hidden or absent), silent (no report then)."""
    gate = fs.gate
    names = np.asarray(CLASSES)[step_classes(steps, gate)]
    for name in dict.fromkeys(names):
        for first, last in _spans(t[names == name]):
            ax.axvspan(first - 0.5, last + 0.5, color=QUALITY_COLOURS[name], lw=0, zorder=1)
    ax.set_ylim(0, 1)
    ax.set_yticks([])
    ax.set_title(f"(i) track quality judged by the truth (gate {gate:g} m)", loc="left", fontsize=10)
    handles = [Patch(color=QUALITY_COLOURS[c], label=QUALITY_LABELS[c]) for c in CLASSES]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.6), fontsize=7, frameon=False, ncol=2)


JAM_COLOUR = "#e00000"


def snapshot_steps(agents: Columns, fs: FigureSettings, T: int, N: int) -> tuple[tuple[int, str], tuple[int, str]]:
    """The steps of panels (g) and (h), each with the reason it was chosen, as in the paper's Fig. 3:
    (g) shows the team when one of its agents receives the most interference from the others'
    cones (the paper's step 16, where agent 1 is jammed), the earliest such step, or the middle
    step when no agent ever receives any; (h) shows the last step."""
    received = np.nan_to_num(agent_table(agents, "interference_w", T, N), nan=0.0)
    if received.max(initial=0.0) > 0:
        k, i = np.unravel_index(np.argmax(received), received.shape)  # row-major: the earliest step
        db = 10 * np.log10(received[k, i])
        first = (int(k) + 1, f"the most interference,\n{db:.1f} dBW at agent {int(i) + 1} "
                             f"(delta {fs.interference_limit_db:g} dBW)")
    else:
        first = ((T + 1) // 2, "the middle step\n(no agent receives interference)")
    return first, (T, "the last step\n(cones while on; red ring: jammed)")


def _panel_cones(ax, steps, agents, fs, T, N, k: int, title: str) -> None:
    """(g), (h): at step ``k`` the agents u_t (jammed ones ringed in red), their sensing cones
    while transmitting (apex at the agent, axis to the point the antenna aimed at, height h_a,
    full angle theta_a), the true target (black star) and the fused estimate (cyan)."""
    ant = fs.antenna
    u = agent_positions(agents, T, N)[k - 1]
    point = agent_positions(agents, T, N, "point_")[k - 1]
    power = agent_table(agents, "power_w", T, N)[k - 1]
    jammed = agent_table(agents, "jammed", T, N)[k - 1] > 0
    shown = [u]
    for j in range(N):
        if not (power[j] > 0 and np.isfinite(point[j]).all() and np.isfinite(u[j]).all()):
            continue
        v, tri = cone_mesh(u[j], point[j], ant.height, ant.half_angle)
        c = agent_colour(j)
        ax.add_collection3d(Poly3DCollection(v[tri], facecolor=c, edgecolor="none", alpha=0.14))
        rim = v[1:-1]
        ax.plot(*np.vstack([rim, rim[:1]]).T, color=c, lw=0.8)
        ax.plot(*np.stack([u[j], u[j] + ant.height * axis_of(u[j], point[j])]).T, color=c, lw=0.8, ls="--")
        shown.append(v)
    for j in range(N):
        ax.scatter(*u[j], color=agent_colour(j), marker="o", s=50, edgecolor="k", depthshade=False)
        if jammed[j]:
            ax.scatter(*u[j], facecolor="none", edgecolor=JAM_COLOUR, marker="o", s=190, lw=1.6, depthshade=False)
    truth = steps_xyz(steps, "truth_")[k - 1]
    est = steps_xyz(steps, "est_")[k - 1]
    if np.isfinite(truth).all():
        ax.scatter(*truth, color=TRUTH_COLOUR, marker="*", s=110, depthshade=False)
        shown.append(truth[None])
    if np.isfinite(est).all():
        ax.scatter(*est, color=ESTIMATE_COLOUR, marker="D", s=30, depthshade=False)
        shown.append(est[None])
    lo, hi = path_box(np.vstack(shown), fs)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-9))
    ax.tick_params(labelsize=7)
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y"), (ax.zaxis, "z")):  # a narrow axis had piled up its labels
        axis.set_major_locator(matplotlib.ticker.MaxNLocator(3))
        axis.set_label_text(f"{name} [m]", fontsize=7)
        axis.labelpad = -2
    ax.set_title(title, fontsize=9)
