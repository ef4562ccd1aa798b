"""The mixed birth inside the preset `pursuit`, measured again after its measurement-driven
births were kept inside the area (docs/holding.md, "The mixed birth kept inside the area"):
`filter.birth: mixed` paired against the preset on the same 300 trials (trials of experiment
seed 44, fresh seeds drawn from it, none used before).

Run: python docs/birth_mixed.py [OUT]   (default runs/experiment-birth-mixed; two spawned
         workers, a few minutes; copy its summary.csv, paired.csv, timing.csv and figure into
         docs/experiments/birth-mixed/ to update the docs)"""

import sys

from trackjam.experiments.definitions import EXPERIMENTS, Experiment, against_preset

NAME = "birth-mixed"
TRIALS, SEED_OF_EXPERIMENT = 300, 44


def experiment() -> Experiment:
    return against_preset(NAME, "pursuit against pursuit with the mixed birth kept inside the area",
                          "pursuit + filter.birth: mixed", {"filter.birth": "mixed"}, "pursuit -> mixed birth")


if __name__ == "__main__":  # the workers are spawned and import this file again
    from trackjam.experiments.engine import run_experiment

    EXPERIMENTS[NAME] = experiment()
    out = sys.argv[1] if len(sys.argv) > 1 else f"runs/experiment-{NAME}"
    run_experiment(NAME, trials=TRIALS, steps=30, seed=SEED_OF_EXPERIMENT, workers=2, out=out)
