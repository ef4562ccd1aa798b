"""Draws docs/reacquisition.png from a run of `trackjam experiment oracles`: how often the preset
`pursuit` holds the target again after the Fig. 3 occlusion, beside the same preset told what
no real team knows (``oracle.*``), with each row's Clopper-Pearson 95 % interval (summary.csv)
and its sign test against the preset (paired.csv), and the issue's 40 % line.

Run: python docs/reacquisition.py [OUT]   (OUT: the experiment's folder, by default
runs/experiment-oracles; the figure is written beside this script)"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from trackjam.experiments.summary import read_table  # noqa: E402

TARGET = 0.40  # the 8 of 20


def main(folder: Path = Path("runs/experiment-oracles"), out: Path = Path(__file__).with_name("reacquisition.png")) -> None:
    rows = read_table(folder / "summary.csv")
    p_of = {int(r["b"]): r for r in read_table(folder / "paired.csv")}
    fig, ax = plt.subplots(figsize=(10.0, 0.55 * len(rows) + 1.8), layout="constrained")
    y = np.arange(len(rows))[::-1]
    for yi, r in zip(y, rows):
        k, n = int(r["reacquired"]), int(r["reacquired_of"])
        share, lo, hi = k / n, float(r["reacquired_lo"]), float(r["reacquired_hi"])
        preset = int(r["config"]) == 1
        ax.barh(yi, share, color="tab:blue" if preset else "tab:gray", alpha=0.8)
        ax.errorbar(share, yi, xerr=[[share - lo], [hi - share]], color="black", capsize=3, lw=1)
        note = f"{k} of {n}"
        if not preset:
            pair = p_of[int(r["config"])]
            p = pair["reacquired_p"]
            note += f"; +{pair['reacquired_gained']} / -{pair['reacquired_lost']}, p = " + (f"{float(p):.1g}" if p else "-")
        ax.text(hi + 0.01, yi, note, va="center", fontsize=8)
    ax.axvline(TARGET, color="tab:red", ls="--", lw=1)
    ax.text(TARGET + 0.005, y[0] + 0.5, "issue's target (8 of 20)", color="tab:red", fontsize=8)
    ax.set_yticks(y, [r["label"] for r in rows], fontsize=8)
    ax.set_xlim(0, min(1.0, max(float(r["reacquired_hi"]) for r in rows) + 0.38))
    ax.set_xlabel("share of trials held again after the occlusion (Clopper-Pearson 95 %)\n"
                  "beside each oracle: trials gained / lost against the preset, and the sign test's p")
    ax.set_title(f"Re-acquisition after the Fig. 3 occlusion: the preset and its oracles ({rows[0]['trials']} trials)",
                 fontsize=10)
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main(*(Path(a) for a in sys.argv[1:2]))
