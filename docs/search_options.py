"""The three search options that each moved re-acquisition a little, not significantly, taken
together inside the preset `pursuit` (docs/holding.md, "The small options together"):
`filter.team_proposals`, `control.belief_at_least: 1` and `filter.visibility.per_particle`,
paired against the preset on the same 300 trials (trials of experiment seed 41, fresh seeds
drawn from it, none of the seeds 1-1200 used before).

Run: python docs/search_options.py [OUT]   (default runs/experiment-search-options; two spawned
         workers, a few minutes; copy its summary.csv and paired.csv into
         docs/experiments/search-options/ to update the docs)"""

import sys

from trackjam.experiments.definitions import EXPERIMENTS, Experiment, against_preset

NAME = "search-options"
TRIALS, SEED_OF_EXPERIMENT = 300, 41
TOGETHER = {"filter.team_proposals": True, "control.belief_at_least": 1, "filter.visibility.per_particle": True}


def experiment() -> Experiment:
    return against_preset(NAME, "pursuit against pursuit with three search options together",
                          "team_proposals + belief_at_least 1 + per_particle", TOGETHER,
                          "pursuit -> the three together")


if __name__ == "__main__":  # the workers are spawned and import this file again
    from trackjam.experiments.engine import run_experiment

    EXPERIMENTS[NAME] = experiment()
    out = sys.argv[1] if len(sys.argv) > 1 else f"runs/experiment-{NAME}"
    run_experiment(NAME, trials=TRIALS, steps=30, seed=SEED_OF_EXPERIMENT, workers=2, out=out)
