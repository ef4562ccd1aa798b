"""Interactive 3D replay of one run: a self-contained HTML page (plotly.js inlined, works offline).

One plotly frame per step t (at most ``MAX_FRAMES``: a longer run shows every k-th step, the
first and the last, and says so in its title bar), with a time slider and play/pause buttons.
Trails pass through the last ``TRAIL_FRAMES`` shown steps, so the page grows with the number
of frames, not with the run's length. Each frame shows the
agents u_t^j with their sensing cones (apex at the agent, axis toward the point the antenna
aimed at, height h_a along the axis, full opening angle theta_a: docs/model.md, Antenna), the true
target and the fused estimate with their trails, the agents that are jammed (red ring, the sum of
the power received from the others >= delta) and a dashed red link from each sender j to a
receiver i it jams by itself (R_ij >= delta). An antenna that is off draws no cone; a cone that
reaches past the area's walls is cut there (the scene's axes are the area, and plotly would
otherwise draw it outside them).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import to_hex

from trackjam.radio.antenna import AntennaModel
from trackjam.viz.figure import (
    ESTIMATE_COLOUR,
    JAM_COLOUR,
    QUALITY_COLOURS,
    QUALITY_LABELS,
    TRUTH_COLOUR,
    Columns,
    agent_colour,
    agent_positions,
    agent_table,
    cone_mesh,
    interference_per_step,
    level_labels,
    run_shape,
    steps_xyz,
)
from trackjam.errors import counted
from trackjam.metrics.track_quality import CLASSES, step_classes
from trackjam.viz.settings import FigureSettings

MAX_FRAMES = 150  # the page and its memory stay bounded whatever the run's length
TRAIL_FRAMES = 60  # a trail shows the last 60 shown steps (all of a run of up to 60 steps)


Trace = dict  # a plotly trace as plain data: building plotly objects for every frame costs minutes


def _xyz(p: np.ndarray) -> dict[str, list]:
    """x, y, z lists of an (n, 3) array, to the millimetre; NaN (a gap) as None."""
    p = np.round(np.atleast_2d(np.asarray(p, dtype=float)), 3)
    return {ax: [float(v) if np.isfinite(v) else None for v in p[:, i]] for i, ax in enumerate("xyz")}


def drawable_box(low, high) -> tuple[np.ndarray, np.ndarray]:
    """The area's corners moved inward onto the millimetre grid :func:`_xyz` rounds to, so that a
    vertex inside this box is still inside the area once rounded."""
    return (np.ceil(np.round(np.asarray(low, dtype=float) * 1000, 6)) / 1000,
            np.floor(np.round(np.asarray(high, dtype=float) * 1000, 6)) / 1000)


def clip_mesh_to_box(vertices: np.ndarray, faces: np.ndarray, low, high) -> tuple[np.ndarray, np.ndarray]:
    """The triangles ``faces`` of ``vertices`` cut to the box [low, high]: a triangle inside stays,
    one outside goes, one across a wall keeps its part inside (one triangle or two), so the mesh
    ends at the walls (open there, as a cone meeting a wall is seen). A mesh inside the box is
    returned as it is; otherwise a triangle soup: vertices (3 m, 3), faces ``arange(3 m)``,
    orientation kept. An empty result has no faces."""
    vertices = np.asarray(vertices, dtype=float)
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    if np.all((vertices >= low) & (vertices <= high)):
        return vertices, faces
    tri = vertices[np.asarray(faces)]  # (m, 3 corners, 3 coordinates)
    for axis in range(3):
        for bound, sign in ((low[axis], 1.0), (high[axis], -1.0)):
            d = sign * (tri[:, :, axis] - bound)  # >= 0 inside this wall
            inside = d >= 0
            n_in = inside.sum(axis=1)
            keep = tri[n_in == 3]
            parts = [keep]
            for count in (1, 2):
                sel = n_in == count
                if not sel.any():
                    continue
                t, dd = tri[sel], d[sel]
                # turn each triangle (cyclically, so its orientation stays) to start at its one
                # corner inside (count 1) or its one corner outside (count 2)
                odd = inside[sel] if count == 1 else ~inside[sel]
                first = np.argmax(odd, axis=1)
                order = (first[:, None] + np.arange(3)) % 3
                rows = np.arange(len(t))[:, None]
                t, dd = t[rows, order], dd[rows, order]
                v0, v1, v2 = t[:, 0], t[:, 1], t[:, 2]
                d0, d1, d2 = dd[:, 0:1], dd[:, 1:2], dd[:, 2:3]
                p01 = v0 + d0 / (d0 - d1) * (v1 - v0)
                p02 = v0 + d0 / (d0 - d2) * (v2 - v0)
                p01[:, axis] = bound
                p02[:, axis] = bound
                if count == 1:  # v0 inside: the corner at v0
                    parts.append(np.stack([v0, p01, p02], axis=1))
                else:  # v0 outside: the quadrilateral v1 v2 p02 p01, as two triangles
                    parts.append(np.stack([v1, v2, p02], axis=1))
                    parts.append(np.stack([v1, p02, p01], axis=1))
            tri = np.concatenate(parts, axis=0)
    tri = np.clip(tri, low, high)  # what rounding of the cuts left a hair outside
    return tri.reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3)


def _cone_trace(j: int, apex, point, on: bool, ant: AntennaModel, low, high) -> Trace:
    """The cone of agent ``j`` cut to the box [low, high] (the area, :func:`drawable_box`): the
    replay draws nothing outside the area."""
    v = f = None
    if on and np.all(np.isfinite(apex)) and np.all(np.isfinite(point)):
        v, f = clip_mesh_to_box(*cone_mesh(apex, point, ant.height, ant.half_angle), low, high)
    if f is None or len(f) == 0:  # a degenerate cone at the agent: nothing to see, the trace stays in place
        at = np.clip(np.nan_to_num(np.asarray(apex, dtype=float)), low, high)
        v = np.repeat(at[None, :], 3, axis=0)
        f = np.array([[0, 1, 2]])
    return dict(
        type="mesh3d", **_xyz(v), i=f[:, 0].tolist(), j=f[:, 1].tolist(), k=f[:, 2].tolist(),
        color=agent_colour(j), opacity=0.18, flatshading=True, hoverinfo="skip",
        name=f"cone {j + 1}", legendgroup=f"agent{j}", showlegend=False,
    )


def _trail(p: np.ndarray, name: str, colour: str, width: float, **kw) -> Trace:
    return dict(type="scatter3d", **_xyz(p), mode="lines", name=name,
                line=dict(color=colour, width=width), hoverinfo="skip", **kw)


def _point(p: np.ndarray, name: str, colour: str, symbol: str, size: float, text=None,
           **kw) -> Trace:
    return dict(type="scatter3d", **_xyz(p), mode="markers+text" if text else "markers",
                name=name, text=text, textposition="top center",
                marker=dict(color=colour, symbol=symbol, size=size), **kw)


def shown_steps(T: int, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """0-based indices of the steps that get a frame: all of them up to ``max_frames``, else
    ``max_frames`` evenly spread ones, the first and the last included."""
    if T <= max_frames:
        return np.arange(T)
    return np.unique(np.round(np.linspace(0, T - 1, max_frames)).astype(int))


def _frame_data(f, shown, steps, truth, est, u, u_path, point, idx, power, jammed, R, ant, labels, delta,
                quality, box):
    """All traces of frame ``f`` (step index ``shown[f]``), always in the same order (plotly
    frames update by index). Trails pass through the last ``TRAIL_FRAMES`` shown steps. The
    estimate is drawn in its step's track-quality colour (the run figure's band (i)), so a false
    track does not look held."""
    k = shown[f]
    path = shown[max(f + 1 - TRAIL_FRAMES, 0): f + 1]
    data = [
        _trail(truth[path], "target trail", TRUTH_COLOUR, 4, showlegend=False),
        _point(truth[k], "target (truth)", TRUTH_COLOUR, "diamond", 6),
        _trail(est[path], "estimate trail", ESTIMATE_COLOUR, 3, showlegend=False),
        _point(est[k], "reported estimate (colour: track quality)", to_hex(QUALITY_COLOURS[quality[k]]),
               "circle-open", 7),
    ]
    return data + team_traces(f, shown, u, u_path, point, idx, power, jammed, R, ant, labels, delta, box)


def team_traces(f, shown, u, u_path, point, idx, power, jammed, R, ant, labels, delta, box,
                hover_extra=None) -> list[Trace]:
    """The team's traces of frame ``f`` (step index ``shown[f]``), the same in every replay: each
    agent's trail, marker (its level) and cone, the jammed agents' red rings and the jamming
    links. ``hover_extra(k, j)``, when given, adds a line to agent j's hover text at step k."""
    k = shown[f]
    N = u.shape[1]
    path = shown[max(f + 1 - TRAIL_FRAMES, 0): f + 1]
    data = []
    # u_path row 0 is the start, row k + 1 is step k
    agent_path = np.concatenate([[0], path + 1]) if path[0] == 0 else path + 1
    for j in range(N):
        data.append(_trail(u_path[agent_path, j], f"trail {j + 1}", agent_colour(j), 2,
                           legendgroup=f"agent{j}", showlegend=False, opacity=0.6))
    for j in range(N):
        label = f"{j + 1}: {labels[int(idx[k, j])]}"
        data.append(_point(u[k, j], f"agent {j + 1}", agent_colour(j), "circle", 6, text=[label],
                           legendgroup=f"agent{j}",
                           hovertext=[f"agent {j + 1}<br>level {labels[int(idx[k, j])]}"
                                      f"<br>interference {_db(R[f, j].sum())}"
                                      + (f"<br>{hover_extra(k, j)}" if hover_extra else "")],
                           hoverinfo="text"))
    for j in range(N):
        data.append(_cone_trace(j, u[k, j], point[k, j], power[k, j] > 0, ant, *box))
    hit = np.flatnonzero(jammed[k])
    # a trace with no point leaves the legend: an empty step gets one NaN point instead
    data.append(_point(u[k, hit] if len(hit) else np.full((1, 3), np.nan), "jammed agent (red ring)",
                       JAM_COLOUR, "circle-open", 16))
    seg = []
    for i, j in zip(*np.nonzero(R[f] >= delta)):
        seg += [u[k, j], u[k, i], [np.nan] * 3]
    seg = np.asarray(seg or [[np.nan] * 3], dtype=float).reshape(-1, 3)
    data.append(dict(type="scatter3d", **_xyz(seg), mode="lines", name="jams (sender -> receiver)",
                     line=dict(color=JAM_COLOUR, width=3, dash="dash"), hoverinfo="skip"))
    return data


def _db(w: float) -> str:
    return "0 W" if w <= 0 else f"{10 * np.log10(w):.1f} dBW"


def _title(steps: Columns, k: int, quality: np.ndarray | None = None) -> str:
    e = float(steps["existence"][k])
    ospa = float(steps["ospa"][k])
    exists = bool(steps["target_exists"][k])
    seen = bool(steps["target_detectable"][k])
    state = "present" if seen else ("occluded" if exists else "absent")
    title = (f"t = {int(steps['t'][k])}   |   fused existence {e:.2f}   |   OSPA {ospa:.2f} m"
             f"   |   target {state}   |   received at target {_db(float(steps['target_received_w'][k]))}")
    if quality is not None:
        title += f"   |   track quality: {QUALITY_LABELS[quality[k]]}"
    if "mode" in steps:  # the loop's planning mode, when it logs one
        title += f"   |   planning: {steps['mode'][k]}"
    return title


def team_arrays(agents: Columns, fs: FigureSettings, T: int, N: int, shown: np.ndarray) -> tuple:
    """What :func:`team_traces` draws, from a run's agents log: positions u (T, N, 3), the paths
    with the start as row 0 (T + 1, N, 3), the aims (T, N, 3), level indices, transmit powers,
    jammed (T, N), the interference R of the shown steps (row f is step ``shown[f]``) and the
    level labels."""
    u = agent_positions(agents, T, N)
    u_path = np.concatenate([agent_positions(agents, T, N, "prev_")[:1], u], axis=0)
    point = agent_positions(agents, T, N, "point_")
    idx = agent_table(agents, "level_index", T, N)
    power = np.nan_to_num(agent_table(agents, "power_w", T, N))
    jammed = agent_table(agents, "jammed", T, N) > 0.5
    R = interference_per_step(agents, fs, shown)  # row f is step shown[f]
    return u, u_path, point, idx, power, jammed, R, level_labels(fs)


def replay_figure(steps: Columns, agents: Columns, fs: FigureSettings, max_frames: int = MAX_FRAMES) -> dict:
    """The plotly figure of the replay, as plain data (``data``, ``layout``, ``frames``): one
    frame per shown step, slider and play/pause buttons."""
    T, N = run_shape(steps, agents, fs)
    shown = shown_steps(T, max_frames)
    truth = steps_xyz(steps, "truth_")
    est = steps_xyz(steps, "est_")
    ant = fs.antenna
    u, u_path, point, idx, power, jammed, R, labels = team_arrays(agents, fs, T, N, shown)
    quality = np.asarray(CLASSES)[step_classes(steps, fs.gate)]

    box = drawable_box(fs.low, fs.high)  # the cones are cut at the area's walls
    every = "" if len(shown) == T else f"   |   {len(shown)} of {T} steps shown"
    frames = [
        dict(
            name=str(int(steps["t"][k])),
            data=_frame_data(f, shown, steps, truth, est, u, u_path, point, idx, power, jammed, R, ant,
                             labels, ant.delta_w, quality, box),
            layout=dict(title=dict(text=_title(steps, k, quality) + every)),
        )
        for f, k in enumerate(shown)
    ]
    note = replay_note(fs, fs.name, counted(N, "agent"), T, len(shown), ant)
    return dict(data=frames[0]["data"], layout=replay_layout(frames, fs, note), frames=frames)


def replay_note(fs: FigureSettings, name: str, who: str, T: int, n_shown: int, ant: AntennaModel) -> str:
    """The page's note under the plot: the run (``who``: its counts of agents, and targets), its
    steps and how often a frame is shown, the solver, the cones and delta."""
    return (f"{name}: {who}, {counted(T, 'step')}"
            + (f" (a frame every {T / n_shown:.2g} steps)" if n_shown < T else "")
            + f", solver {fs.solver}; "
            f"cones: h_a = {ant.height:g} m, theta_a = {fs.opening_angle_deg:g} deg; "
            f"delta = {fs.interference_limit_db:g} dBW")


def replay_layout(frames: list[dict], fs: FigureSettings, note: str) -> dict:
    """The layout every replay shares: the area as the scene's axes, the first frame's title,
    play/pause buttons, the time slider over ``frames`` and ``note`` at the top right."""
    lo, hi = fs.low, fs.high
    span = hi - lo
    ratio = span / span.max()
    play = dict(frame=dict(duration=600, redraw=True), transition=dict(duration=0),
                fromcurrent=True, mode="immediate")
    pause = dict(frame=dict(duration=0, redraw=False), transition=dict(duration=0), mode="immediate")
    slider_steps = [
        dict(method="animate", label=f["name"],
             args=[[f["name"]], dict(frame=dict(duration=0, redraw=True), transition=dict(duration=0),
                                  mode="immediate")])
        for f in frames
    ]
    layout = dict(
        title=dict(text=frames[0]["layout"]["title"]["text"], x=0.02, font=dict(size=14)),
        scene=dict(
            xaxis=dict(range=[float(lo[0]), float(hi[0])], title=dict(text="x [m]"), autorange=False),
            yaxis=dict(range=[float(lo[1]), float(hi[1])], title=dict(text="y [m]"), autorange=False),
            zaxis=dict(range=[float(lo[2]), float(hi[2])], title=dict(text="z [m]"), autorange=False),
            aspectmode="manual",
            aspectratio=dict(x=float(ratio[0]), y=float(ratio[1]), z=float(ratio[2])),
            camera=dict(eye=dict(x=1.5, y=-1.5, z=0.9)),
            domain=dict(x=[0.0, 1.0], y=[0.12, 1.0]),  # the slider keeps the bottom: its labels had sat on the axes'
        ),
        uirevision="replay",
        modebar=dict(orientation="v"),  # on the right edge, off the long title
        legend=dict(x=0.0, y=0.98, bgcolor="rgba(255,255,255,0.7)"),
        margin=dict(l=0, r=0, t=50, b=0),
        updatemenus=[dict(
            type="buttons", direction="left", x=0.02, y=0.02, xanchor="left", yanchor="bottom",
            pad=dict(r=10, t=10), showactive=False,
            buttons=[dict(label="Play", method="animate", args=[None, play]),
                     dict(label="Pause", method="animate", args=[[None], pause])],
        )],
        sliders=[dict(
            active=0, x=0.18, y=0.02, len=0.8, xanchor="left", yanchor="bottom",
            currentvalue=dict(prefix="t = ", font=dict(size=13)), pad=dict(t=10),
            steps=slider_steps,
        )],
        annotations=[dict(
            text=note,
            x=0.97, y=0.99, xref="paper", yref="paper", xanchor="right", showarrow=False,
            font=dict(size=11, color="#555"),
        )],
    )
    import plotly.io as pio

    layout["template"] = pio.templates[pio.templates.default].to_plotly_json()  # the look plotly's own figures get
    return layout


def write_replay(steps: Columns, agents: Columns, fs: FigureSettings, path: str | Path) -> Path:
    """Write the replay of one run as a self-contained HTML file at ``path``; returns the path."""
    path = Path(path)
    return write_page(replay_figure(steps, agents, fs), f"trackjam replay: {fs.name} (solver {fs.solver})", path)


def write_page(fig: dict, title: str, path: Path) -> Path:
    """Write the replay figure ``fig`` as a self-contained HTML page (plotly.js inlined) at
    ``path``, its tab named ``title``; returns the path."""
    import plotly.io as pio

    # validate=False: the traces are plain data, built to plotly's schema (the browser test loads them)
    html = pio.to_html(fig, validate=False, include_plotlyjs=True, include_mathjax=False, full_html=True,
                       auto_play=False, config=dict(displaylogo=False, responsive=True),
                       div_id="trackjam-replay", default_width="100%", default_height="100vh")
    # the plot fills the window: no page margin, no scroll bar; the tab names the run (it had no
    # <title>, so every replay's tab and bookmark read "replay.html")
    import html as markup

    title = markup.escape(title)
    html = html.replace("<head>", f"<head><title>{title}</title>"
                        "<style>html, body {margin: 0; height: 100%; overflow: hidden}</style>", 1)
    path.write_text(html, encoding="utf-8")
    return path
