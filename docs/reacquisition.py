"""Draws docs/reacquisition.png: how often a team holds the target again after the Fig. 3
occlusion, the preset `pursuit` against the oracles of docs/holding.md, with the Clopper-Pearson
95 % intervals of the experiments' tables (``trackjam.experiments.summary.count_ci95``). The counts are those of docs/holding.md's tables (patched runs; the oracles are not
options). Run: python docs/reacquisition.py"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from trackjam.experiments.summary import count_ci95  # noqa: E402

# (label, seeds re-acquired, seeds run, kind); kind: the preset, an oracle or the target
ROWS = [
    ("the preset, seeds 1-600", 166, 600, "preset"),
    ("its particles at step 13 redrawn tight\naround its own mean", 183, 600, "oracle"),
    ("... shifted so that their mean is\nthe true state", 200, 600, "oracle"),
    ("... redrawn tight around the true state", 251, 600, "oracle"),
    ("the preset, seeds 101-200", 31, 100, "preset"),
    ("after any detection from step 18 on,\nit plans at the truth for 3 steps", 39, 100, "oracle"),
    ("its filter told that the occluded\nscans carry no target", 41, 100, "oracle"),
    ("an earlier preset, seeds 101-200", 18, 100, "preset"),
    ("it plans at the truth at step 18\n(the target reappears)", 41, 100, "oracle"),
    ("... at steps 18-20", 52, 100, "oracle"),
]
TARGET = 0.40  # the 8 of 20


def share_ci95(k: int, n: int) -> tuple[float, float]:
    """The Clopper-Pearson 95 % interval on k / n, as the experiments' tables give it."""
    _, _, lo, hi = count_ci95([1] * k + [0] * (n - k))
    return lo, hi


def main(out: Path = Path(__file__).with_name("reacquisition.png")) -> None:
    fig, ax = plt.subplots(figsize=(8.0, 5.4), layout="constrained")
    y = np.arange(len(ROWS))[::-1]
    for yi, (label, k, n, kind) in zip(y, ROWS):
        lo, hi = share_ci95(k, n)
        colour = "tab:blue" if kind == "preset" else "tab:gray"
        ax.barh(yi, k / n, color=colour, alpha=0.8)
        ax.errorbar(k / n, yi, xerr=[[k / n - lo], [hi - k / n]], color="black", capsize=3, lw=1)
        ax.text(hi + 0.01, yi, f"{k} of {n}", va="center", fontsize=8)
    ax.axvline(TARGET, color="tab:red", ls="--", lw=1)
    ax.text(TARGET + 0.005, y[0] + 0.55, "issue's target (8 of 20)", color="tab:red", fontsize=8)
    ax.set_yticks(y, [r[0] for r in ROWS], fontsize=8)
    ax.set_xlim(0, 0.7)
    ax.set_xlabel("share of seeds held again after the occlusion (Clopper-Pearson 95 % interval)")
    ax.set_title("Re-acquisition after the Fig. 3 occlusion: the preset and what the oracles are told", fontsize=10)
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
