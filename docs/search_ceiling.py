"""How soon could any team find the Fig. 3 target again after the occlusion? Runs the preset
`pursuit` and the reach-free searcher of ``trackjam.metrics.search`` on the same truths, and
writes docs/experiments/search/first_detection.csv and docs/search_ceiling.png.

For each seed: the step of the team's first detection of the target after the occlusion (any
agent, the target's own measurement) and whether the team held it again; the searcher's first
detection when it is told the true state at the last step before the occlusion (``told``), and
when it is told it as well as a Kalman filter can know it from one position fix per step of
``FIX_SD`` m per axis, about what the three agents' scans give together (``kalman``); each
placed anywhere (reach-free) and bound by the agents' moves from where the team's agents were
when the target vanished (``_bound``).

Three of the searcher's advantages are then taken away, one at a time and together, from the
bound searcher told as a Kalman filter knows (docs/experiments/search/ablations.csv): knowing when
the target is hidden (``_blind``: it looks, and weighs the misses, on the hidden steps too), and
aiming each antenna where it serves best (``_one_aim``: all at its belief's mean).

Run: python docs/search_ceiling.py [FIRST LAST]            (seeds, by default 1 300; 2 spawned workers),
     python docs/search_ceiling.py ablations [FIRST LAST]  (the second table),
     python docs/search_ceiling.py figure                  (the figure and both summaries from the CSVs)"""

import multiprocessing as mp
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from trackjam.experiments.backends import one_numba_thread  # the pool's workers: one numba thread each

PARTICLES, ITERATIONS = 2000, 150  # the searcher's belief and its placement's local search
FIX_SD = 0.35  # [m] per axis: range noise 0.8 m and 3.6 deg of bearing at 5-6 m, three agents
HERE = Path(__file__).parent
TABLE = HERE / "experiments" / "search" / "first_detection.csv"
FIGURE = HERE / "search_ceiling.png"
LABELS = {"team": "the team (preset `pursuit`)",
          "told": "searcher told the true state, placed anywhere",
          "kalman": "searcher told it as a Kalman filter knows it, placed anywhere",
          "told_bound": "searcher told the true state, from the team's positions, 5 m a step",
          "kalman_bound": "searcher told it as a Kalman filter knows it, from the team's positions, 5 m a step",
          "kalman_bound_blind": "the last, not knowing when the target is hidden",
          "kalman_bound_one_aim": "the last, every antenna aimed at its belief's mean",
          "kalman_bound_team_like": "the last, both: like the team"}
# name: (told as a Kalman filter knows it, bound by the moves, knows when it is hidden, aims free)
SPECS = {"told": (False, False, True, True), "kalman": (True, False, True, True),
         "told_bound": (False, True, True, True), "kalman_bound": (True, True, True, True),
         "kalman_bound_blind": (True, True, False, True), "kalman_bound_one_aim": (True, True, True, False),
         "kalman_bound_team_like": (True, True, False, False)}
VARIANTS = ("told", "kalman", "told_bound", "kalman_bound")
ABLATIONS = ("kalman_bound_blind", "kalman_bound_one_aim", "kalman_bound_team_like")
ABLATION_TABLE = TABLE.with_name("ablations.csv")
TEAM = ("seed", "last_seen", "team_first", "team_reacquired", "team_chance")


def columns(variants: tuple[str, ...]) -> tuple[str, ...]:
    return (*TEAM, *(f"{v}_first" for v in variants), *(f"{v}_chance" for v in variants))


COLUMNS = columns(VARIANTS)


def one(seed: int, variants: tuple[str, ...] = VARIANTS) -> dict:
    """One seed's row: the team's run and each of ``variants``' searches on its truth."""
    from trackjam.config.loading import load_scenario
    from trackjam.metrics.search import kalman_floor, search_after
    from trackjam.simulation.engine import Simulation

    sim = Simulation(load_scenario("pursuit", seed=seed))
    c, truth = sim.c, sim.truth
    states, detectable = [None], [False]  # the run's own truth, step by step
    while not sim.done:
        sim.step()
        states.append(None if truth.state is None else truth.state.copy())
        detectable.append(truth.detectable)
    r = sim.result()
    last_seen = c.target.occlusions[0][0] - 1
    back = first_searched(detectable, last_seen)
    A = r.agents
    after = (A["t"] > last_seen) & A["detected"]
    team_first = int(A["t"][after].min()) if after.any() else None
    team_chance = float(1 - np.prod(1 - A["p_d"][A["t"] == back]))
    row = {"seed": seed, "last_seen": last_seen, "team_first": team_first,
           "team_reacquired": bool(r.summary["reacquired_after_last_spell"]), "team_chance": team_chance}
    ant, low, high = c.antenna, c.low, c.high
    at = A["t"] == last_seen
    positions = np.stack([A["x"][at], A["y"][at], A["z"][at]], axis=1)  # the team's, when the target vanished
    reach = float(np.linalg.norm(c.displacements, axis=1).max())
    kalman = kalman_floor(c.target.accel_var, FIX_SD)
    for name in variants:
        informed, bound, knows_hidden, aims_free = SPECS[name]
        rng = np.random.default_rng(np.random.SeedSequence([seed, list(SPECS).index(name)]))
        moves = {"positions": positions, "reach": reach} if bound else {}
        found = search_after(states, np.array(detectable), last_seen, ant, c.target.accel_var, low, high, rng,
                             n_agents=c.n_agents, sd=kalman if informed else (0.0, 0.0), particles=PARTICLES,
                             iterations=ITERATIONS, knows_hidden=knows_hidden, aims_free=aims_free, **moves)
        row[f"{name}_first"] = found.first
        on_back = np.flatnonzero(found.searched == back)  # its chance on the step the target is back
        row[f"{name}_chance"] = float(found.chance[on_back[0]]) if len(on_back) else float("nan")
    return row


def first_searched(detectable: list[bool], last_seen: int) -> int:
    return next(t for t in range(last_seen + 1, len(detectable)) if detectable[t])


def main(first: int = 1, last: int = 300, variants: tuple[str, ...] = VARIANTS, table: Path = TABLE) -> None:
    rows = []
    with ProcessPoolExecutor(2, mp_context=mp.get_context("spawn"), initializer=one_numba_thread) as ex:
        for i, row in enumerate(ex.map(one, range(first, last + 1), [variants] * (last - first + 1)), 1):
            rows.append(row)
            print(f"seed {row['seed']}: first detection: team {row['team_first']}, "
                  + ", ".join(f"{v} {row[v + '_first']}" for v in variants) + f" ({i} of {last - first + 1})",
                  flush=True)
    table.parent.mkdir(parents=True, exist_ok=True)
    with table.open("w") as f:
        f.write(",".join(columns(variants)) + "\n")
        for row in rows:
            f.write(",".join("" if row[k] is None else str(row[k]) for k in columns(variants)) + "\n")
    print(table)
    if variants == VARIANTS:
        figure()
    else:
        print("\n".join(summary(read(table), variants)))


def read(path: Path = TABLE) -> list[dict]:
    from trackjam.experiments.summary import read_table

    return read_table(path)


def first_by(rows: list[dict], who: str, t: int) -> list[int]:
    """1 where ``who`` had its first detection after the occlusion by step ``t``, else 0."""
    return [int(r[f"{who}_first"] != "" and int(r[f"{who}_first"]) <= t) for r in rows]


def summary(rows: list[dict], variants: tuple[str, ...] = VARIANTS, last: int = 30) -> list[str]:
    """One line per searcher: seeds with a first detection by step ``last`` (Clopper-Pearson
    95 %), on the first searched step, and the sign test against the team, seed by seed."""
    from trackjam.experiments.summary import count_ci95, sign_test

    team = first_by(rows, "team", last)
    lines = []
    for who in ("team", *variants):
        k, n, lo, hi = count_ci95(first_by(rows, who, last))
        at = int(rows[0]["last_seen"]) + 5  # the first step after the Fig. 3 occlusion
        k18 = sum(first_by(rows, who, at))
        line = f"{who}: {k} of {n} ({k / n:.0%}, {lo:.0%}-{hi:.0%}) by step {last}, {k18} at step {at}"
        if who != "team":
            g, l, p = sign_test(zip(team, first_by(rows, who, last)))
            line += f"; against the team +{g} / -{l}, p = {p:.1g}"
        lines.append(line)
    held = sum(r["team_reacquired"] == "True" for r in rows)
    lines.append(f"team held the target again: {held} of {len(rows)} ({held / len(rows):.0%})")
    return lines


def figure(path: Path = TABLE, out: Path = FIGURE, ablations: Path = ABLATION_TABLE) -> None:
    """The share of seeds with a first detection by each step: the team, the four searchers and,
    from the ablations' table, the searcher that knows what the team knows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read(path)
    start = int(rows[0]["last_seen"]) + 5
    steps = np.arange(start, 31)
    fig, ax = plt.subplots(figsize=(9.0, 5.0), layout="constrained")
    styles = {"team": ("black", "-"), "told": ("tab:green", "--"), "kalman": ("tab:blue", "--"),
              "told_bound": ("tab:green", "-"), "kalman_bound": ("tab:blue", "-")}
    for who in ("team", *VARIANTS):
        share = [np.mean(first_by(rows, who, t)) for t in steps]
        color, ls = styles[who]
        ax.plot(steps, share, color=color, ls=ls, marker="o", ms=3, lw=2 if who == "team" else 1.4, label=LABELS[who])
    like = read(ablations)
    share = [np.mean(first_by(like, "kalman_bound_team_like", t)) for t in steps]
    ax.plot(steps, share, color="tab:gray", ls="-", marker="s", ms=3, lw=1.4,
            label="searcher bound as the last, not knowing when it is hidden, one aim (as the team)")
    held = np.mean([r["team_reacquired"] == "True" for r in rows])
    ax.axhline(held, color="black", ls=":", lw=1)
    ax.text(steps[-1], held - 0.035, f"the team holds it again (confirmed within 5 m) at some step: {held:.0%}",
            fontsize=8, ha="right")
    ax.axhline(0.40, color="tab:red", ls=":", lw=1)
    ax.text(steps[-1], 0.41, "the issue's 40 % (held again)", color="tab:red", fontsize=8, ha="right")
    ax.set_xlabel("step (the target reappears at step %d)" % start)
    ax.set_ylabel("share of seeds with a first detection after the occlusion by this step")
    ax.set_ylim(0, 1)
    ax.set_title(f"Finding the Fig. 3 target again: the team and a searcher with every advantage but knowing "
                 f"where it is ({len(rows)} seeds)", fontsize=9)
    ax.legend(fontsize=7.5, loc="lower right")
    fig.savefig(out, dpi=110)
    print(out)
    print("\n".join(summary(rows)))


if __name__ == "__main__":
    if sys.argv[1:2] == ["figure"]:
        figure()
        print("\n".join(summary(read(ABLATION_TABLE), ABLATIONS)[1:-1]) if ABLATION_TABLE.exists() else "")
    elif sys.argv[1:2] == ["ablations"]:
        main(*map(int, sys.argv[2:4]), variants=ABLATIONS, table=ABLATION_TABLE)
    else:
        main(*map(int, sys.argv[1:3]))
