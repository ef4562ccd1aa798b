"""Quality shares where they do not apply (NaN: a trial without a detectable step, or without an
undetectable spell) in summary.csv and paired.csv: each configuration's mean and interval are
over the trials where the share is defined, each pair's differences over the trials where both
are, and ``STEM_trials`` says how many. Checked against a plain computation (the statistics
module, not numpy) on hand-made records. summary.csv wrote an empty mean for a configuration
with one such trial, while paired.csv left the trial out of its differences."""

from __future__ import annotations

import math
import statistics

import pytest
from scipy import stats

from trackjam.experiments.engine import run_experiment
from trackjam.experiments.summary import (
    COUNTS,
    METRICS,
    QUALITY,
    WHERE_DEFINED,
    count_ci95,
    paired_rows,
    read_table,
    table_rows,
)

NAN = math.nan
CONF = {"n_controls": 79, "opening_angle_deg": 80.0, "constraints": True, "solver": "exact"}
CONFIGURATIONS = [{"config": c, "label": f"variant {c}", **CONF} for c in (1, 2)]
# held_share of trials 0-4 under each configuration: NaN where the trial had no detectable step
HELD = {1: [0.5, NAN, 0.75, 0.25, NAN], 2: [0.625, 0.5, NAN, 0.5, 0.875]}
CEILING = {1: [1.0, NAN, 0.875, 0.75, 0.5], 2: [1.0, NAN, 0.875, 0.75, 0.5]}  # the same truths
REACQUIRED = {1: [1.0, NAN, 0.0, NAN, 1.0], 2: [1.0, NAN, 1.0, NAN, 1.0]}
OSPA = {1: [4.0, 6.0, 5.0, 3.0, 7.0], 2: [3.5, 6.5, 4.0, 3.0, 5.0]}


def _records() -> list[dict]:
    return [{"config": c, "trial": k, "held_share": HELD[c][k], "ceiling_share": CEILING[c][k],
             "reacquired_after_last_spell": REACQUIRED[c][k], "ospa_mean": OSPA[c][k]}
            for c in (1, 2) for k in range(5)]


METRICS_HERE = (("held", "held_share", ""), ("ceiling", "ceiling_share", ""), ("ospa", "ospa_mean", ""))


def plain(values: list[float]) -> tuple[float, float, int]:
    """Mean, t-based 95 % half-width and count of the values that are not NaN, by hand."""
    x = [v for v in values if not math.isnan(v)]
    n = len(x)
    return sum(x) / n, stats.t.ppf(0.975, n - 1) * statistics.stdev(x) / math.sqrt(n), n


def _binomial_tail(n: int, p: float, ks) -> float:
    return math.fsum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in ks)


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper-Pearson) interval by its definition, without scipy: the lower bound is
    the p at which P(X >= k) = (1 - level) / 2, the upper the p at which P(X <= k) = (1 - level) / 2
    (X ~ Binomial(n, p); 0 at k = 0, 1 at k = n). Each tail is monotone in p: bisection."""
    a = (1 - level) / 2

    def root(f) -> float:  # f increasing on [0, 1], f(0) < 0 < f(1)
        lo, hi = 0.0, 1.0
        for _ in range(200):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if f(mid) < 0 else (lo, mid)
        return (lo + hi) / 2

    low = 0.0 if k == 0 else root(lambda p: _binomial_tail(n, p, range(k, n + 1)) - a)
    high = 1.0 if k == n else root(lambda p: a - _binomial_tail(n, p, range(k + 1)))
    return low, high


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 13, 30])
def test_a_counts_interval_is_the_clopper_pearson_95_percent_interval(n):
    """count_ci95's bounds against the exact interval worked out from the binomial tails (a
    Wilson or a 90 % interval, or a k or n miscounted, passed the tests that only asked for
    lo <= k / n <= hi); NaN and None are trials where the count does not apply."""
    for k in range(n + 1):
        got = count_ci95([1.0] * k + [NAN, None] + [0.0] * (n - k))
        assert got[:2] == (k, n)
        assert got[2:] == pytest.approx(clopper_pearson(k, n), rel=1e-9, abs=1e-12), (k, n)
    assert count_ci95([NAN, None])[:2] == (0, 0) and all(math.isnan(v) for v in count_ci95([NAN, None])[2:])


def test_the_closed_form_tells_the_intervals_apart():
    """The reference is not loose: the 95 % interval of 3 of 5 differs from its 90 % one and from
    the Wilson interval by far more than the tolerance above."""
    lo95, hi95 = clopper_pearson(3, 5)
    lo90, hi90 = clopper_pearson(3, 5, 0.90)
    assert lo95 < lo90 - 0.02 and hi95 > hi90 + 0.02
    z, n, p = stats.norm.ppf(0.975), 5, 3 / 5
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    assert abs((centre - half) - lo95) > 0.02 and abs((centre + half) - hi95) > 0.02


def test_the_quality_shares_are_the_ones_that_may_be_undefined():
    assert {key for _, key, _ in QUALITY} <= WHERE_DEFINED
    assert not {key for _, key, _ in METRICS} & WHERE_DEFINED  # defined in every trial: no count column


def test_summary_means_a_share_over_the_trials_where_it_is_defined():
    rows = table_rows(_records(), CONFIGURATIONS, METRICS_HERE, COUNTS)
    for row, c in zip(rows, (1, 2)):
        assert row["trials"] == 5
        for stem, values in (("held", HELD[c]), ("ceiling", CEILING[c])):
            mean, ci, n = plain(values)
            assert (row[f"{stem}_mean"], row[f"{stem}_ci95"], row[f"{stem}_trials"]) == (
                pytest.approx(mean), pytest.approx(ci), n)
        assert (row["ospa_mean"], row["ospa_ci95"]) == (pytest.approx(plain(OSPA[c])[0]), pytest.approx(plain(OSPA[c])[1]))
        assert "ospa_trials" not in row
        k = sum(v == 1 for v in REACQUIRED[c])
        assert (row["reacquired"], row["reacquired_of"]) == (k, 3)
        assert (row["reacquired_lo"], row["reacquired_hi"]) == pytest.approx(clopper_pearson(k, 3), rel=1e-9, abs=1e-12)
    assert [k for k in rows[0] if k.startswith("held")] == ["held_mean", "held_ci95", "held_trials"]
    assert rows[0]["held_trials"] == 3 and rows[1]["held_trials"] == 4


def test_a_paired_difference_is_over_the_trials_where_both_are_defined():
    row = paired_rows(_records(), [(1, 2, "one -> two")], METRICS_HERE)[0]
    assert row["trials"] == 5
    both = [k for k in range(5) if not math.isnan(HELD[1][k]) and not math.isnan(HELD[2][k])]
    assert both == [0, 3]
    mean, ci, n = plain([HELD[2][k] - HELD[1][k] for k in both])
    assert (row["held_diff"], row["held_ci95"], row["held_trials"]) == (pytest.approx(mean), pytest.approx(ci), 2)
    assert (row["ceiling_diff"], row["ceiling_ci95"], row["ceiling_trials"]) == (0.0, 0.0, 4)
    mean, ci, _ = plain([b - a for a, b in zip(OSPA[1], OSPA[2])])
    assert (row["ospa_diff"], row["ospa_ci95"]) == (pytest.approx(mean), pytest.approx(ci))
    assert [k for k in row if k.startswith("held")] == ["held_diff", "held_ci95", "held_trials"]


def test_a_share_defined_in_no_trial_has_no_mean_and_a_count_of_zero():
    records = [{"config": 1, "trial": k, "held_share": NAN} for k in range(3)]
    records += [{"config": 2, "trial": k, "held_share": 0.5} for k in range(3)]
    metrics = (("held", "held_share", ""),)
    row = table_rows(records, CONFIGURATIONS, metrics)[0]
    assert math.isnan(row["held_mean"]) and math.isnan(row["held_ci95"]) and row["held_trials"] == 0
    pair = paired_rows(records, [(1, 2, "one -> two")], metrics)[0]
    assert math.isnan(pair["held_diff"]) and pair["held_trials"] == 0 and pair["trials"] == 3


def _trial_with_undefined_shares(scenario) -> dict:
    """A cheap trial whose shares do not apply in some trials (by its seed's parity and its
    opening angle): the figures every record of the constraints experiment holds."""
    odd = scenario.seed % 2 == 1
    constrained = scenario.control.constraints
    shares = {"held_share": NAN if odd and constrained else 0.25 + 0.5 * (scenario.seed % 3 == 0),
              "false_track_share": 0.0, "missed_share": NAN if odd else 0.5,
              "ceiling_share": 1.0 - 0.125 * (scenario.seed % 4)}
    return {"jamming_incidents_per_agent": 1.0, "jamming_incidents": [1], "target_received_w_mean": 1.0,
            "agent_received_w_mean": 0.1, "transmit_w_mean": 0.1, "ospa_mean": 2.0 + scenario.seed % 5,
            "reacquired_after_last_spell": NAN, "step_s_mean": 0.01, "solve_s_mean": 0.001, **shares}


def test_the_files_state_the_trials_each_mean_and_difference_is_over(tmp_path):
    out = tmp_path / "e"
    result = run_experiment("constraints", trials=6, steps=2, seed=7, workers=1, progress="none", out=out,
                            trial=_trial_with_undefined_shares)
    import pyarrow.parquet as pq

    recs = {(r["config"], r["trial"]): r for r in (pq.read_table(p).to_pylist()[0] for p in (out / "trials").iterdir())}
    summary, paired = read_table(out / "summary.csv"), read_table(out / "paired.csv")
    for row in summary:
        c = int(row["config"])
        for stem, key in (("held", "held_share"), ("missed", "missed_share"), ("ceiling", "ceiling_share")):
            values = [recs[(c, k)][key] for k in range(6)]
            n = sum(not math.isnan(v) for v in values)
            assert int(row[f"{stem}_trials"]) == n
            if n:
                assert float(row[f"{stem}_mean"]) == pytest.approx(plain(values)[0], rel=1e-5)
            else:
                assert row[f"{stem}_mean"] == ""
    (pair,) = paired
    a, b = int(pair["a"]), int(pair["b"])
    for stem, key in (("held", "held_share"), ("ceiling", "ceiling_share")):
        d = [recs[(b, k)][key] - recs[(a, k)][key] for k in range(6)
             if not math.isnan(recs[(a, k)][key]) and not math.isnan(recs[(b, k)][key])]
        assert int(pair[f"{stem}_trials"]) == len(d) and float(pair[f"{stem}_diff"]) == pytest.approx(
            sum(d) / len(d), rel=1e-5, abs=1e-9)
    assert result.summary[0]["held_trials"] < 6 and result.summary[0]["held_mean"] == result.summary[0]["held_mean"]
