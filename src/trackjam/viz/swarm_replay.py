"""Interactive 3D replay of a run with several targets (the swarm engine): the one-target replay's
page (:mod:`trackjam.viz.replay`: self-contained HTML, plotly.js inlined, at most ``MAX_FRAMES``
frames, trails through the last ``TRAIL_FRAMES`` shown steps, time slider and play/pause) drawn
from the swarm logs.

Each frame shows every true target with its trail in its own colour (the run figure's, named in
the legend, outlined in black; a diamond while it flies, a cross once its jamming fail-safe has
started: downed; nothing while it is absent), every reported track as a labelled ring in the
colour of the target it holds that step (grey while it holds none: a false track), and the team
as the one-target replay draws it (:func:`trackjam.viz.replay.team_traces`): each agent's trail,
its level, its cone toward the point its antenna aimed at (``point_x/y/z`` of the agents log)
cut at the area's walls, the jammed agents' red rings and the jamming links.
"""

from __future__ import annotations

import html as markup
from pathlib import Path

import numpy as np
from matplotlib.colors import to_hex

from trackjam.errors import counted
from trackjam.viz.replay import (
    MAX_FRAMES,
    TRAIL_FRAMES,
    Trace,
    _point,
    _trail,
    drawable_box,
    replay_layout,
    replay_note,
    shown_steps,
    team_arrays,
    team_traces,
    write_page,
)
from trackjam.viz.settings import FigureSettings
from trackjam.viz.swarm import NONE_COLOUR, target_colours

TARGET_OUTLINE = "black"
TRACKS_NAME = "reported tracks (colour: the target held; grey: false)"


def _text(s: str) -> str:
    """A user's text (a target's id) as plotly shows it: its own characters, no markup."""
    return markup.escape(str(s))


def swarm_shape(tables: dict) -> tuple[int, int, list[str]]:
    """(T, N, ids): steps, agents and the targets' ids of a swarm run's logs, or one ValueError."""
    for name in ("steps", "targets", "tracks", "agents"):
        if name not in tables:
            raise ValueError(f"not a swarm run's logs: no {name} table")
    t = np.asarray(tables["steps"]["t"])
    T = len(t)
    if T == 0 or not np.array_equal(t, np.arange(1, T + 1)):
        raise ValueError("steps: t must run 1, 2, ... with one row per step")
    ag = tables["agents"]
    N = int(np.max(ag["agent"])) + 1 if len(ag["agent"]) else 0
    if N == 0 or len(ag["t"]) != T * N:
        raise ValueError(f"agents: expected one row per step and agent, got {len(ag['t'])} rows")
    ids = list(dict.fromkeys(str(i) for i in tables["targets"]["target"]))
    if len(tables["targets"]["t"]) != T * len(ids):
        raise ValueError("targets: expected one row per step and target")
    return T, N, ids


def _by_step(tables: dict, T: int) -> list[np.ndarray]:
    """Per step (0-based), the row indices of the tracks table."""
    t = np.asarray(tables["tracks"]["t"], dtype=int)
    order = np.argsort(t, kind="stable")
    bounds = np.searchsorted(t[order], np.arange(1, T + 2))
    return [order[bounds[k]: bounds[k + 1]] for k in range(T)]


def _target_traces(f, shown, k_id, name, colour, truth, downed, exists) -> list[Trace]:
    """Target ``k_id``'s trail and marker in frame ``f`` (NaN, nothing drawn, while absent)."""
    k = shown[f]
    path = shown[max(f + 1 - TRAIL_FRAMES, 0): f + 1]
    here = truth[k, k_id] if exists[k, k_id] else np.full(3, np.nan)
    state = "downed (fail-safe)" if downed[k, k_id] else "flying"
    marker = _point(here, f"target {name}", colour, "x" if downed[k, k_id] else "diamond", 8,
                    text=[f"{name}{' (downed)' if downed[k, k_id] else ''}"], legendgroup=f"target{k_id}",
                    hovertext=[f"target {name}<br>{state}"], hoverinfo="text")
    # outlined in black: the agents' colours are the same palette's
    marker["marker"]["line"] = dict(color=TARGET_OUTLINE, width=2)
    return [
        _trail(truth[path, k_id], f"target {name} trail", colour, 4, legendgroup=f"target{k_id}",
               showlegend=False),
        marker,
    ]


def _tracks_trace(rows, tr, hold, colours) -> Trace:
    """The reported tracks of one step: a ring each, labelled, in the colour of the target it
    holds (grey: none). A step without tracks gets one NaN point (the trace stays in the legend)."""
    if len(rows) == 0:
        return _point(np.full((1, 3), np.nan), TRACKS_NAME, NONE_COLOUR, "circle-open", 8)
    est = np.stack([tr[f"est_{a}"][rows] for a in "xyz"], axis=1)
    colour = [colours[h] if h >= 0 else NONE_COLOUR for h in hold[rows]]
    labels = [_text(s) for s in tr["track"][rows]]
    held = [f"holds target {_text(g)}" if g else "false track (holds no target)" for g in tr["target"][rows]]
    hover = [f"track {lab}<br>{h}<br>existence {float(e):.2f}" for lab, h, e in
             zip(labels, held, tr["existence"][rows])]
    trace = _point(est, TRACKS_NAME, NONE_COLOUR, "circle-open", 8, text=labels, hovertext=hover,
                   hoverinfo="text")
    trace["marker"]["color"] = colour
    trace["textfont"] = dict(size=10)
    return trace


def _title(steps, tg_held, tracks_held, k: int) -> str:
    n_tracks = int(steps["tracks"][k])
    false = n_tracks - int(tracks_held[k])
    return (f"t = {int(steps['t'][k])}   |   targets present {int(steps['targets_present'][k])}, "
            f"detectable {int(steps['targets_detectable'][k])}, held {int(tg_held[k].sum())}"
            f"   |   tracks reported {n_tracks} ({false} false)"
            f"   |   OSPA {float(steps['ospa'][k]):.2f} m (cardinality {float(steps['ospa_card'][k]):.2f})"
            f"   |   planning: {steps['mode'][k]}")


def swarm_replay_figure(tables: dict, fs: FigureSettings, max_frames: int = MAX_FRAMES) -> dict:
    """The plotly figure of a swarm run's replay, as plain data (``data``, ``layout``,
    ``frames``): one frame per shown step, its traces always in the same order: per target its
    trail and marker, the reported tracks, then the team (:func:`trackjam.viz.replay.team_traces`)."""
    T, N, ids = swarm_shape(tables)
    K = len(ids)
    steps, tg, tr, ag = tables["steps"], tables["targets"], tables["tracks"], tables["agents"]
    shown = shown_steps(T, max_frames)
    truth = np.stack([np.asarray(tg[f"truth_{a}"], dtype=float) for a in "xyz"], axis=1).reshape(T, K, 3)
    exists = np.asarray(tg["exists"], dtype=bool).reshape(T, K)
    downed = np.asarray(tg["downed"], dtype=bool).reshape(T, K)
    held = np.asarray(tg["held"], dtype=bool).reshape(T, K)
    colours = [to_hex(c) for c in target_colours(K)]
    names = [_text(i) for i in ids]
    hold = np.array([ids.index(str(x)) if str(x) in ids else -1 for x in tr["target"]], dtype=np.int64)
    per_step = _by_step(tables, T)
    tracks_held = np.array([int((hold[r] >= 0).sum()) for r in per_step])
    ant = fs.antenna
    u, u_path, point, idx, power, jammed, R, labels = team_arrays(ag, fs, T, N, shown)
    serves = np.full((T, N), "", dtype=object)
    serves[np.asarray(ag["t"], dtype=int) - 1, np.asarray(ag["agent"], dtype=int)] = [str(s) for s in ag["serves"]]
    mode = np.full((T, N), "", dtype=object)
    mode[np.asarray(ag["t"], dtype=int) - 1, np.asarray(ag["agent"], dtype=int)] = [str(s) for s in ag["mode"]]

    def served(k: int, j: int) -> str:
        return f"{mode[k, j]}: serves {_text(serves[k, j])}" if serves[k, j] else str(mode[k, j])

    box = drawable_box(fs.low, fs.high)  # the cones are cut at the area's walls
    every = "" if len(shown) == T else f"   |   {len(shown)} of {T} steps shown"
    frames = []
    for f, k in enumerate(shown):
        data = []
        for i in range(K):
            data += _target_traces(f, shown, i, names[i], colours[i], truth, downed, exists)
        data.append(_tracks_trace(per_step[k], tr, hold, colours))
        data += team_traces(f, shown, u, u_path, point, idx, power, jammed, R, ant, labels, ant.delta_w, box,
                            hover_extra=served)
        frames.append(dict(name=str(int(steps["t"][k])), data=data,
                           layout=dict(title=dict(text=_title(steps, held, tracks_held, k) + every))))
    note = replay_note(fs, _text(fs.name), f"{counted(K, 'target')}, {counted(N, 'agent')}", T, len(shown), ant)
    return dict(data=frames[0]["data"], layout=replay_layout(frames, fs, note), frames=frames)


def write_swarm_replay(tables: dict, fs: FigureSettings, path: str | Path) -> Path:
    """Write the replay of a swarm run (its logs ``tables``) as a self-contained HTML file at
    ``path``; returns the path."""
    return write_page(swarm_replay_figure(tables, fs), f"trackjam replay: {fs.name} (solver {fs.solver})",
                      Path(path))

