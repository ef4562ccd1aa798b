"""run.png of a run with several targets (ours): every target and track in its own colour, and
which agent serves which.

Left, the area seen from above: each target's true path (solid, its colour), each reported
track's estimates (dots, the colour of the target it holds that step, grey while it holds none:
a false track), the agents' paths (thin black). Right, from the top: which target each agent's
served track holds per step (its colour; grey: a track holding no target; white: hovering);
each target held or not per step; the multi-target OSPA with its cardinality part.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402

from trackjam.viz.settings import FigureSettings, save_figure  # noqa: E402

NONE_COLOUR = "#bbbbbb"


def target_colours(k: int) -> list:
    return [plt.get_cmap("tab10")(i % 10) for i in range(k)]


def served_targets(tables: dict, ids: list[str]) -> np.ndarray:
    """(T, N): index of the target held by the track each agent serves; -1 a track holding no
    target, -2 hovering."""
    ag, tr = tables["agents"], tables["tracks"]
    T, N = len(tables["steps"]["t"]), int(ag["agent"].max()) + 1
    holds = {(int(t), str(lab)): tg for t, lab, tg in zip(tr["t"], tr["track"], tr["target"])}
    out = np.full((T, N), -2, dtype=np.int64)
    for t, j, lab in zip(ag["t"], ag["agent"], ag["serves"]):
        if lab:
            tg = holds.get((int(t), str(lab)), "")
            out[int(t) - 1, int(j)] = ids.index(tg) if tg in ids else -1
    return out


def plot_swarm(tables: dict, fs: FigureSettings, path: str | Path) -> Path:
    path = Path(path)
    steps, tg, tr, ag = tables["steps"], tables["targets"], tables["tracks"], tables["agents"]
    t = np.asarray(steps["t"], dtype=float)
    T = len(t)
    ids = list(dict.fromkeys(str(i) for i in tg["target"]))
    # a text id is the user's: its dollar signs are literal, not matplotlib's mathtext (an id
    # "$\frac{$" had failed the figure with a ParseSyntaxException after the whole run)
    shown = [name.replace("$", r"\$") for name in ids]
    K, N = len(ids), int(ag["agent"].max()) + 1
    colours = target_colours(K)
    fig = plt.figure(figsize=(15, 8), layout="constrained")
    grid = fig.add_gridspec(3, 2, width_ratios=[1.0, 1.2], height_ratios=[1.2, 0.8, 1.0])
    top = fig.add_subplot(grid[:, 0])
    for j in range(N):
        rows = ag["agent"] == j
        top.plot(ag["x"][rows], ag["y"][rows], color="black", lw=0.8, alpha=0.6)
        top.annotate(f"{j + 1}", (ag["x"][rows][-1], ag["y"][rows][-1]), fontsize=8)
    for k, name in enumerate(ids):
        rows = tg["target"] == name
        top.plot(tg["truth_x"][rows], tg["truth_y"][rows], color=colours[k], lw=2.2, label=f"target {shown[k]}")
        seen = np.flatnonzero(np.isfinite(tg["truth_x"][rows]))  # where it first appears: its path's direction
        if len(seen):
            top.plot(tg["truth_x"][rows][seen[0]], tg["truth_y"][rows][seen[0]], "o", color=colours[k], ms=7,
                     mec="black", gid="target start")
    hold = np.array([ids.index(x) if x in ids else -1 for x in tr["target"]], dtype=np.int64)
    dot = [colours[h] if h >= 0 else NONE_COLOUR for h in hold]
    top.scatter(tr["est_x"], tr["est_y"], c=dot, s=12, marker="o", edgecolors="none")
    top.scatter([], [], c=NONE_COLOUR, s=12, label="reported tracks (grey: false)")
    top.plot([], [], "o", color="white", mec="black", ms=7, label="where a target appears")
    top.set_xlim(fs.low[0], fs.high[0])
    top.set_ylim(fs.low[1], fs.high[1])
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title(f"{fs.name}: targets, tracks (dots) and agents (black, numbered at their end), from above")
    top.legend(loc="upper left", fontsize=8)

    serve = served_targets(tables, ids)
    cmap = ListedColormap(["white", NONE_COLOUR, *colours])
    ax = fig.add_subplot(grid[0, 1])
    ax.imshow(serve.T + 2, aspect="auto", cmap=cmap, vmin=0, vmax=K + 1, interpolation="nearest",
              extent=(0.5, T + 0.5, N + 0.5, 0.5))
    ax.set_ylabel("agent")
    ax.set_yticks(range(1, N + 1))
    ax.set_title("target held by the track each agent serves (grey: none; white: hovering)")
    held = tg["held"].reshape(T, K)
    detectable = tg["detectable"].reshape(T, K)
    band = np.where(held, np.arange(K)[None, :] + 2, np.where(detectable, 1, 0))
    ax2 = fig.add_subplot(grid[1, 1], sharex=ax)
    ax2.imshow(band.T, aspect="auto", cmap=cmap, vmin=0, vmax=K + 1, interpolation="nearest",
               extent=(0.5, T + 0.5, K - 0.5, -0.5))
    ax2.set_yticks(range(K), [f"target {name}" for name in shown])
    ax2.set_title("held (its colour), missed (grey), not detectable (white)")
    ax3 = fig.add_subplot(grid[2, 1], sharex=ax)
    ax3.plot(t, steps["ospa"], color="black", label="OSPA")
    ax3.plot(t, steps["ospa_card"], color="tab:red", ls="--", label="its cardinality part")
    ax3.set_ylim(0, fs.ospa_cutoff * 1.05)
    ax3.set_xlabel("time step t  (dT = 1 s)")
    ax3.set_ylabel(f"OSPA (p={fs.ospa_order:g}, c={fs.ospa_cutoff:g}) [m]")
    ax3.legend(loc="upper left", fontsize=8)
    ax3.set_xlim(0.5, T + 0.5)
    save_figure(fig, path)
    plt.close(fig)
    return path
