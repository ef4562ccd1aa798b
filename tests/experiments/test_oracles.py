"""`trackjam experiment oracles`: the preset beside the preset told what no real team knows,
and the sign test that pairs their re-acquisitions."""

from __future__ import annotations

import io
import math
from contextlib import redirect_stdout

from hypothesis import given, strategies as st
import numpy as np
import pytest

from trackjam.experiments.cli import experiment_command
from trackjam.experiments.definitions import (
    EXPERIMENTS,
    ORACLE_VARIANTS,
    base_data,
    preset_settings,
    trial_scenario,
)
from trackjam.experiments.summary import COUNTS, paired_rows, read_table, sign_test
from trackjam.experiments.trials import TrialDraw

OUTCOME = st.sampled_from([0.0, 1.0, math.nan, None])


def closed_form_p(gained: int, lost: int) -> float:
    """Two-sided exact sign test: twice the smaller binomial tail at 1/2, at most 1."""
    n = gained + lost
    k = min(gained, lost)
    return min(1.0, 2.0 * sum(math.comb(n, i) for i in range(k + 1)) / 2**n)


@given(st.lists(st.tuples(OUTCOME, OUTCOME), max_size=40))
def test_sign_test_counts_the_discordant_pairs_and_matches_the_closed_form(pairs):
    gained, lost, p = sign_test(pairs)
    defined = [(a, b) for a, b in pairs if a is not None and b is not None and not (math.isnan(a) or math.isnan(b))]
    assert gained == sum(1 for a, b in defined if (a, b) == (0.0, 1.0))
    assert lost == sum(1 for a, b in defined if (a, b) == (1.0, 0.0))
    if gained + lost == 0:
        assert math.isnan(p)
    else:
        assert p == pytest.approx(closed_form_p(gained, lost), rel=1e-9)


def test_sign_test_small_cases_by_hand():
    assert sign_test([(0, 1)] * 6) == (6, 0, pytest.approx(2 / 64))
    assert sign_test([(0, 1), (1, 0), (1, 1), (0, 0)]) == (1, 1, pytest.approx(1.0))


def test_paired_rows_carry_the_sign_test_of_each_count():
    key = COUNTS[0][1]
    records = [{"config": c, "trial": k, key: v} for c, values in ((1, [0, 0, 1, math.nan]), (2, [1, 1, 1, 1]))
               for k, v in enumerate(values)]
    (row,) = paired_rows(records, [(1, 2, "a -> b")], (), COUNTS)
    assert (row["reacquired_gained"], row["reacquired_lost"]) == (2, 0)
    assert row["reacquired_p"] == pytest.approx(0.5)


def test_each_oracle_row_is_the_preset_and_one_oracle():
    experiment = EXPERIMENTS["oracles"]
    preset = preset_settings("pursuit")
    assert ORACLE_VARIANTS[0][1] == preset
    base = base_data(experiment, steps=30)
    seen = set()
    for configuration in experiment.configurations:
        extra = {k: v for k, v in configuration.settings.items() if k not in preset}
        assert all(configuration.settings[k] == v for k, v in preset.items())
        assert len(extra) == (0 if configuration.index == 1 else 1)
        assert all(k.startswith("oracle.") for k in extra)
        seen |= set(extra)
        s = trial_scenario(experiment, base, configuration, TrialDraw(0, np.zeros(6), np.zeros((3, 3))), seed=0)
        assert (s.oracle is None) == (configuration.index == 1)
        assert s.antenna.pointing == "aim" and s.control.solver == "exact"
    assert seen == {"oracle.state_before_hiding", "oracle.truth_after_hiding", "oracle.follow_up",
                    "oracle.empty_hidden_scans", "oracle.mean_before_hiding", "oracle.point_after_hiding"}
    assert experiment.pairs == tuple((1, c.index, f"preset pursuit -> {c.label}")
                                     for c in experiment.configurations[1:])


def test_a_short_run_writes_the_table_the_pairs_and_their_sign_tests(tmp_path):
    printed = io.StringIO()
    with redirect_stdout(printed):
        experiment_command("oracles", trials=2, steps=7, seed=3, workers=1, out=tmp_path,
                           overrides=["filter.particles=600", "filter.birth_particles=200",
                                      "target.occlusions=[[3, 4]]"])
    rows = read_table(tmp_path / "summary.csv")
    assert [r["label"] for r in rows] == [label for label, _ in ORACLE_VARIANTS]
    paired = read_table(tmp_path / "paired.csv")
    assert len(paired) == len(ORACLE_VARIANTS) - 1
    for row in paired:
        gained, lost = int(row["reacquired_gained"]), int(row["reacquired_lost"])
        assert 0 <= gained + lost <= 2
        assert (row["reacquired_p"] == "") == (gained + lost == 0)
    assert "gained/lost" in printed.getvalue()
    assert (tmp_path / "oracles.png").stat().st_size > 0
