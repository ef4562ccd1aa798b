"""`trackjam experiment holding` on real (short) runs: one row per variant, the track quality of
each trial is the one its own steps give, and every variant faces the same truths, so the
clairvoyant ceiling is the same in every row."""

from __future__ import annotations

import io
import math
from contextlib import redirect_stdout

import numpy as np
import pyarrow.parquet as pq
import pytest

from trackjam.experiments.cli import experiment_command
from trackjam.experiments.definitions import HOLDING_VARIANTS
from trackjam.experiments.summary import read_table
from trackjam.metrics.track_quality import track_quality

# 2 trials x 7 steps, hidden at steps 3-4 so that re-acquisition applies; few particles
SHORT = ["filter.particles=600", "filter.birth_particles=200", "target.occlusions=[[3, 4]]"]


@pytest.fixture(scope="module")
def holding(tmp_path_factory):
    """The experiment's folder and what the command printed."""
    out = tmp_path_factory.mktemp("holding")
    printed = io.StringIO()
    with redirect_stdout(printed):
        experiment_command("holding", trials=2, steps=7, seed=3, workers=1, out=out, overrides=SHORT)
    return out, printed.getvalue()


def test_holding_table_has_one_row_per_variant_and_one_ceiling(holding):
    holding, printed = holding
    rows = read_table(holding / "summary.csv")
    assert [r["label"] for r in rows] == [label for label, _ in HOLDING_VARIANTS]
    assert all(r["solver"] == "exact" and r["trials"] == "2" for r in rows)
    for stem in ("held", "false_track", "missed", "ospa", "incidents", "ceiling"):
        assert all(r[f"{stem}_mean"] != "" and r[f"{stem}_ci95"] != "" for r in rows), stem
    # the same truths for every variant: the chaser's ceiling cannot differ
    assert len({r["ceiling_mean"] for r in rows}) == 1 and len({r["ceiling_ci95"] for r in rows}) == 1
    for r in rows:
        shares = sum(float(r[f"{s}_mean"]) for s in ("held", "false_track", "missed"))
        assert shares == pytest.approx(1.0)
        k, n = int(r["reacquired"]), int(r["reacquired_of"])
        assert n == 2 and 0 <= k <= n
        assert 0.0 <= float(r["reacquired_lo"]) <= k / n <= float(r["reacquired_hi"]) <= 1.0
    assert (holding / "holding.png").stat().st_size > 10_000
    # the closing table shows the holding columns, counts as k/n
    for word in ("held", "false_track", "missed", "reacquired", "ceiling"):
        assert word in printed
    assert f"{rows[0]['reacquired']}/2" in printed


def test_each_trial_is_judged_on_its_own_steps_and_faces_the_same_truth(holding):
    holding, _ = holding
    trials = {}
    for p in sorted((holding / "trials").glob("c*.parquet")):
        rec = pq.read_table(p).to_pylist()[0]
        trials[(rec["config"], rec["trial"])] = rec
    assert len(trials) == 2 * len(HOLDING_VARIANTS)
    for (c, k), rec in trials.items():
        steps = {name[5:]: np.asarray(v, dtype=float) for name, v in rec.items() if name.startswith("step.")}
        steps["target_detectable"] = steps["target_detectable"].astype(bool)
        q = track_quality(steps, 5.0)
        assert rec["held_share"] == pytest.approx(q["held_share"])
        assert rec["false_track_share"] == pytest.approx(q["false_track_share"])
        assert rec["reacquired_after_last_spell"] == float(q["reacquired_after_last_spell"])
        first = trials[(1, k)]
        np.testing.assert_array_equal(rec["step.truth_x"], first["step.truth_x"])
        assert rec["seed"] == first["seed"] and not math.isnan(rec["ceiling_share"])
    assert trials[(1, 0)]["seed"] != trials[(1, 1)]["seed"]  # trial k varies the seed
