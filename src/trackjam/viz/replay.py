"""Interactive 3D replay of one run: a self-contained HTML page (plotly.js inlined, works offline).

One plotly frame per step t, with a time slider and play/pause buttons. Each frame shows the
agents u_t^j with their sensing cones (apex at the agent, axis toward the point the antenna
aimed at, height h_a along the axis, full opening angle theta_a: MODEL.md, Antenna), the true
target and the fused estimate with their trails, the agents that are jammed (red ring, the sum of
the power received from the others >= delta) and a dashed red link from each sender j to a
receiver i it jams by itself (R_ij >= delta). An antenna that is off draws no cone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import plotly.graph_objects as go

from trackjam.config import Scenario
from trackjam.radio.antenna import AntennaModel, axis_of
from trackjam.viz.figure import (
    ESTIMATE_COLOUR,
    TRUTH_COLOUR,
    Columns,
    agent_colour,
    agent_positions,
    agent_table,
    interference_per_step,
    level_labels,
    run_shape,
    steps_xyz,
)

CONE_SEGMENTS = 24
JAM_COLOUR = "#e00000"


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


def _cone_trace(j: int, apex, point, on: bool, ant: AntennaModel) -> go.Mesh3d:
    if on and np.all(np.isfinite(apex)) and np.all(np.isfinite(point)):
        v, f = cone_mesh(apex, point, ant.height, ant.half_angle)
    else:  # a degenerate cone at the agent: nothing to see, the trace stays in place
        v = np.repeat(np.nan_to_num(np.asarray(apex, dtype=float))[None, :], 3, axis=0)
        f = np.array([[0, 1, 2]])
    return go.Mesh3d(
        x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2],
        color=agent_colour(j), opacity=0.18, flatshading=True, hoverinfo="skip",
        name=f"cone {j + 1}", legendgroup=f"agent{j}", showlegend=False,
    )


def _trail(xyz: np.ndarray, upto: int, name: str, colour: str, width: float, **kw) -> go.Scatter3d:
    p = xyz[: upto + 1]
    return go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="lines", name=name,
                        line=dict(color=colour, width=width), hoverinfo="skip", **kw)


def _point(p: np.ndarray, name: str, colour: str, symbol: str, size: float, text=None,
           **kw) -> go.Scatter3d:
    p = np.atleast_2d(np.asarray(p, dtype=float))
    return go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="markers+text" if text else "markers",
                        name=name, text=text, textposition="top center",
                        marker=dict(color=colour, symbol=symbol, size=size), **kw)


def _frame_data(k, steps, u, u_path, point, idx, power, jammed, R, ant, labels, delta):
    """All traces of step t = k + 1, always in the same order (plotly frames update by index)."""
    N = u.shape[1]
    truth = steps_xyz(steps, "truth_")
    est = steps_xyz(steps, "est_")
    data = [
        _trail(truth, k, "target trail", TRUTH_COLOUR, 4, showlegend=False),
        _point(truth[k], "target (truth)", TRUTH_COLOUR, "diamond", 6),
        _trail(est, k, "estimate trail", ESTIMATE_COLOUR, 3, showlegend=False),
        _point(est[k], "fused estimate", ESTIMATE_COLOUR, "circle-open", 7),
    ]
    for j in range(N):
        data.append(_trail(u_path[:, j], k + 1, f"trail {j + 1}", agent_colour(j), 2,
                           legendgroup=f"agent{j}", showlegend=False, opacity=0.6))
    for j in range(N):
        label = f"{j + 1}: {labels[int(idx[k, j])]}"
        data.append(_point(u[k, j], f"agent {j + 1}", agent_colour(j), "circle", 6, text=[label],
                           legendgroup=f"agent{j}",
                           hovertext=[f"agent {j + 1}<br>level {labels[int(idx[k, j])]}"
                                      f"<br>interference {_db(R[k, j].sum())}"],
                           hoverinfo="text"))
    for j in range(N):
        data.append(_cone_trace(j, u[k, j], point[k, j], power[k, j] > 0, ant))
    hit = np.flatnonzero(jammed[k])
    # a trace with no point leaves the legend: an empty step gets one NaN point instead
    data.append(_point(u[k, hit] if len(hit) else np.full((1, 3), np.nan), "jammed agent (red ring)",
                       JAM_COLOUR, "circle-open", 16))
    seg = []
    for i, j in zip(*np.nonzero(R[k] >= delta)):
        seg += [u[k, j], u[k, i], [np.nan] * 3]
    seg = np.asarray(seg or [[np.nan] * 3], dtype=float).reshape(-1, 3)
    data.append(go.Scatter3d(x=seg[:, 0], y=seg[:, 1], z=seg[:, 2], mode="lines",
                             name="jams (sender -> receiver)",
                             line=dict(color=JAM_COLOUR, width=3, dash="dash"), hoverinfo="skip"))
    return data


def _db(w: float) -> str:
    return "0 W" if w <= 0 else f"{10 * np.log10(w):.1f} dBW"


def _title(steps: Columns, k: int) -> str:
    e = float(steps["existence"][k])
    ospa = float(steps["ospa"][k])
    exists = bool(steps["target_exists"][k])
    seen = bool(steps["target_detectable"][k])
    state = "present" if seen else ("occluded" if exists else "absent")
    title = (f"t = {int(steps['t'][k])}   |   fused existence {e:.2f}   |   OSPA {ospa:.2f} m"
             f"   |   target {state}   |   received at target {_db(float(steps['target_received_w'][k]))}")
    if "mode" in steps:  # the loop's planning mode, when it logs one
        title += f"   |   {steps['mode'][k]}"
    return title


def replay_figure(steps: Columns, agents: Columns, scenario: Scenario) -> go.Figure:
    """The plotly figure of the replay: one frame per step, slider and play/pause buttons."""
    T, N = run_shape(steps, agents)
    ant = AntennaModel.from_scenario(scenario)
    u = agent_positions(agents, T, N)
    u_path = np.concatenate([agent_positions(agents, T, N, "prev_")[:1], u], axis=0)
    point = agent_positions(agents, T, N, "point_")
    idx = agent_table(agents, "level_index", T, N)
    power = np.nan_to_num(agent_table(agents, "power_w", T, N))
    jammed = agent_table(agents, "jammed", T, N) > 0.5
    R = interference_per_step(agents, scenario)
    labels = level_labels(scenario)

    frames = [
        go.Frame(
            name=str(int(steps["t"][k])),
            data=_frame_data(k, steps, u, u_path, point, idx, power, jammed, R, ant, labels, ant.delta_w),
            layout=go.Layout(title_text=_title(steps, k)),
        )
        for k in range(T)
    ]
    lo, hi = np.asarray(scenario.area.low, dtype=float), np.asarray(scenario.area.high, dtype=float)
    span = hi - lo
    ratio = span / span.max()
    play = dict(frame=dict(duration=600, redraw=True), transition=dict(duration=0),
                fromcurrent=True, mode="immediate")
    pause = dict(frame=dict(duration=0, redraw=False), transition=dict(duration=0), mode="immediate")
    slider_steps = [
        dict(method="animate", label=f.name,
             args=[[f.name], dict(frame=dict(duration=0, redraw=True), transition=dict(duration=0),
                                  mode="immediate")])
        for f in frames
    ]
    fig = go.Figure(data=frames[0].data, frames=frames)
    fig.update_layout(
        title=dict(text=_title(steps, 0), x=0.02, font=dict(size=14)),
        scene=dict(
            xaxis=dict(range=[lo[0], hi[0]], title="x [m]", autorange=False),
            yaxis=dict(range=[lo[1], hi[1]], title="y [m]", autorange=False),
            zaxis=dict(range=[lo[2], hi[2]], title="z [m]", autorange=False),
            aspectmode="manual",
            aspectratio=dict(x=ratio[0], y=ratio[1], z=ratio[2]),
            camera=dict(eye=dict(x=1.5, y=-1.5, z=0.9)),
        ),
        uirevision="replay",
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
            text=(f"{scenario.name}: {N} agents, {T} steps, solver {scenario.control.solver}; "
                  f"cones: h_a = {ant.height:g} m, theta_a = {scenario.antenna.opening_angle_deg:g} deg; "
                  f"delta = {scenario.antenna.interference_limit_db:g} dBW"),
            x=0.99, y=0.99, xref="paper", yref="paper", xanchor="right", showarrow=False,
            font=dict(size=11, color="#555"),
        )],
    )
    return fig


def write_replay(steps: Columns, agents: Columns, scenario: Scenario, path: str | Path) -> Path:
    """Write the replay of one run as a self-contained HTML file at ``path``; returns the path."""
    path = Path(path)
    fig = replay_figure(steps, agents, scenario)
    html = fig.to_html(include_plotlyjs=True, include_mathjax=False, full_html=True, auto_play=False,
                       config=dict(displaylogo=False, responsive=True), div_id="trackjam-replay",
                       default_width="100%", default_height="100vh")
    # the plot fills the window: no page margin, no scroll bar
    html = html.replace("<head>", "<head><style>html, body {margin: 0; height: 100%; overflow: hidden}</style>", 1)
    path.write_text(html, encoding="utf-8")
    return path
