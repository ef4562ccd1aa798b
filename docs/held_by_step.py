"""Where the held share is won and lost, step by step (docs/holding.md, "Step by step"): the
paper's team with the paper's pointing (`truth`) and with the pointing a real team has (`aim`),
and the preset `pursuit`, on the same 300 trials of Fig. 3 (experiment seed 43, fresh seeds),
rows 1, 2 and 16 of `trackjam experiment holding`. For each step it counts the trials in which
the target is detectable and, of those, the ones whose team holds it (confirmed within 5 m of the
truth) or keeps a false track (confirmed, further off), and the ones in which the clairvoyant
chaser of the ceiling (three agents flying 5 m a step straight at the true target) has an agent
within 8 m of it.

Run:  python docs/held_by_step.py run [OUT]      (default runs/experiment-held-by-step; two
          spawned workers, about ten minutes), then
      python docs/held_by_step.py table OUT      (writes docs/experiments/held-by-step/trials.csv,
          each trial's class at every step, from OUT's trial files, and steps.csv, the counts per
          step; copy OUT's summary.csv and paired.csv beside them), then
      python docs/held_by_step.py figure         (draws docs/held_by_step.png from steps.csv)"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

from trackjam.experiments.definitions import EXPERIMENTS, HOLDING_VARIANTS, _on_fig3

NAME = "held-by-step"
TRIALS, SEED_OF_EXPERIMENT, STEPS = 300, 43, 30
ROWS = (HOLDING_VARIANTS[0], HOLDING_VARIANTS[1], HOLDING_VARIANTS[-1])
HERE = Path(__file__).resolve().parent
TABLE = HERE / "experiments" / NAME / "steps.csv"
TRIALS_TABLE = HERE / "experiments" / NAME / "trials.csv"
FIGURE = HERE / "held_by_step.png"


def experiment():
    return _on_fig3(NAME, "held, false track and the chaser's reach at each step of Fig. 3", ROWS,
                    ((1, 3, f"{ROWS[0][0]} -> {ROWS[2][0]}"), (2, 3, f"{ROWS[1][0]} -> {ROWS[2][0]}")))


def per_step(trial: dict, gate: float, initial: np.ndarray, max_step: float, low, high) -> dict[str, np.ndarray]:
    """One trial's row of a trial file -> per step: its class (track_quality's codes), and 0/1:
    detectable, held, false track, and the chaser within 8 m (at detectable steps), recomputed from
    its per-step series."""
    from trackjam.metrics.ceiling import clairvoyant_ceiling
    from trackjam.metrics.track_quality import FALSE_TRACK, HELD, step_classes

    steps = {k[len("step."):]: np.asarray(v, dtype=float) for k, v in trial.items() if k.startswith("step.")}
    steps["target_detectable"] = detectable = steps["target_detectable"] > 0.5  # stored as 0/1
    classes = step_classes(steps, gate)
    truth = np.stack([steps["truth_x"], steps["truth_y"], steps["truth_z"]], axis=1)
    ceiling = clairvoyant_ceiling(truth, detectable, initial, max_step, low, high)
    return {"classes": classes, "detectable": detectable, "held": classes == HELD, "false_track": classes == FALSE_TRACK,
            "chaser_within_8m": detectable & (ceiling.nearest <= ceiling.d)}


CODES = "HFMPS"  # a step's class, by track_quality's order: held, false track, missed, phantom, silent


def trial_rows(out: Path, trials: int = TRIALS) -> list[dict]:
    """One row per configuration and trial of the trial files in ``out``: its class at every step
    (a letter of CODES) and whether the chaser is within 8 m then (1, 0, or - where the target is
    not detectable); each checked against the trial's own shares."""
    import pyarrow.parquet as pq

    from trackjam.config import load_scenario

    s = load_scenario("paper-fig3")
    initial, max_step = np.asarray(s.agents.initial, float), max(s.agents.radial_steps)
    rows = []
    for config in range(1, len(ROWS) + 1):
        files = sorted((out / "trials").glob(f"c{config:02d}-t*.parquet"))
        if len(files) != trials:
            raise SystemExit(f"{out}: {len(files)} trial files of configuration {config}, not {trials}")
        for f in files:
            trial = {k: v[0] for k, v in pq.read_table(f).to_pydict().items()}
            mine = per_step(trial, s.metrics.gate, initial, max_step, s.area.low, s.area.high)
            # the classes computed again give the trial's own shares, as its run counted them
            n = mine["detectable"].sum()
            for k, share in (("held", "held_share"), ("false_track", "false_track_share"),
                             ("chaser_within_8m", "ceiling_share")):
                if not np.isclose(mine[k].sum() / n, trial[share], rtol=0, atol=1e-12):
                    raise SystemExit(f"{f}: {k} per step does not give the trial's {share}")
            classes = "".join(CODES[c] for c in mine["classes"])
            chaser = "".join("-" if not d else str(int(c)) for d, c in zip(mine["detectable"], mine["chaser_within_8m"]))
            rows.append({"config": config, "trial": int(trial["trial"]), "seed": int(trial["seed"]),
                         "classes": classes, "chaser_within_8m": chaser})
    return rows


def table(trials: list[dict]) -> list[dict]:
    """Per configuration and step, the counts over ``trials`` (rows of :func:`trial_rows`)."""
    rows = []
    for config, (label, _) in enumerate(ROWS, start=1):
        mine = [r for r in trials if r["config"] == config]
        for t in range(STEPS):
            c = [r["classes"][t] for r in mine]
            rows.append({"config": config, "label": label, "t": t + 1,
                         "detectable": sum(x in "HFM" for x in c), "held": c.count("H"),
                         "false_track": c.count("F"),
                         "chaser_within_8m": sum(r["chaser_within_8m"][t] == "1" for r in mine)})
    return rows


def read_csv(path: Path) -> list[dict]:
    """trials.csv (its per-step strings kept as text) or steps.csv, numbers as integers."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    text = ("label", "classes", "chaser_within_8m") if rows and "classes" in rows[0] else ("label",)
    return [{k: (v if k in text else int(v)) for k, v in row.items()} for row in rows]


def draw(rows: list[dict], path: Path = FIGURE) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import beta

    def share(k, n):  # the share and its Clopper-Pearson 95 % interval
        k, n = np.asarray(k), np.asarray(n)
        lo = np.where(k > 0, beta.ppf(0.025, k, n - k + 1), 0.0)
        hi = np.where(k < n, beta.ppf(0.975, k + 1, n - k), 1.0)
        return k / n, lo, hi

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.4), sharex=True)
    colours = ("tab:blue", "tab:orange", "tab:green")
    def series(mine, key):  # per step, NaN where the target is detectable in no trial (a gap in the line)
        n = np.array([r["detectable"] for r in mine], float)
        k = np.array([r[key] for r in mine], float)
        seen = n > 0
        p, lo, hi = (np.full(len(n), np.nan) for _ in range(3))
        p[seen], lo[seen], hi[seen] = share(k[seen], n[seen])
        return p, lo, hi

    for config, colour in zip(range(1, len(ROWS) + 1), colours):
        mine = [r for r in rows if r["config"] == config]
        t = np.array([r["t"] for r in mine])
        for ax, key in ((a, "held"), (b, "false_track")):
            p, lo, hi = series(mine, key)
            ax.plot(t, 100 * p, "-o", ms=3, color=colour, label=mine[0]["label"])
            ax.fill_between(t, 100 * lo, 100 * hi, color=colour, alpha=0.2, lw=0)
    first = [r for r in rows if r["config"] == 1]
    p, _, _ = series(first, "chaser_within_8m")
    a.plot([r["t"] for r in first], 100 * p, "k--", label="ceiling: a clairvoyant chaser within 8 m")
    hidden = [r["t"] for r in rows if r["config"] == 1 and r["detectable"] == 0]
    for ax, title in ((a, "(a) held: confirmed within 5 m of the truth"), (b, "(b) false track: confirmed, > 5 m off")):
        if hidden:
            ax.axvspan(min(hidden) - 0.5, max(hidden) + 0.5, color="0.85", lw=0, label="target occluded")
        ax.set_title(title)
        ax.set_xlabel("step")
        ax.set_ylabel("% of the trials in which the target is detectable")
        ax.set_ylim(0, 100)
        ax.grid(alpha=0.3)
    handles, labels = a.get_legend_handles_labels()
    b.legend(handles, labels, loc="upper right", fontsize=8)  # (b)'s shares stay low: room for it
    n_trials = max(r["detectable"] for r in rows)
    fig.suptitle(f"Fig. 3, exact solver, {n_trials} trials: the share of trials holding the target at each step "
                 "(bands: Clopper-Pearson 95 %)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_csv(rows: list[dict], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":  # the workers are spawned and import this file again
    what = sys.argv[1] if len(sys.argv) > 1 else "run"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(f"runs/experiment-{NAME}")
    if what == "run":
        from trackjam.experiments.engine import run_experiment

        EXPERIMENTS[NAME] = experiment()
        run_experiment(NAME, trials=TRIALS, steps=STEPS, seed=SEED_OF_EXPERIMENT, workers=2, out=out)
    elif what == "table":
        write_csv(trial_rows(out), TRIALS_TABLE)
        write_csv(table(read_csv(TRIALS_TABLE)), TABLE)
    elif what == "figure":
        draw(read_csv(TABLE))
    else:
        raise SystemExit(f"usage: python docs/held_by_step.py run|table|figure [OUT]; got {what!r}")
