"""Per-trial records on disk (one Parquet file each) and the per-configuration tables with
t-based 95% confidence intervals: ``summary.csv`` (deterministic) and ``timing.csv`` (wall
time, which varies from run to run and so is kept out of summary.csv).
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from scipy import stats

from trackjam.files import atomic_write

Metric = tuple[str, str, str]  # (column stem in the tables, key of a trial record, meaning [unit], paper)
METRICS: tuple[Metric, ...] = (
    ("incidents", "jamming_incidents_per_agent", "jamming incidents per trial per agent [steps], Fig. 4(a)/5(a)"),
    ("target_received_w", "target_received_w_mean", "received power at the target, sum over agents [W], Fig. 4(b)/5(c)"),
    ("agent_received_w", "agent_received_w_mean", "interference received per agent [W], Fig. 4(b)/5(b)"),
    ("transmit_w", "transmit_w_mean", "transmit power per agent and step [W], Fig. 4(c)"),
    ("ospa", "ospa_mean", "OSPA tracking error (p=2, c=10 m) [m], Fig. 4(d)/5(d)"),
)
# track quality judged by the truth and the clairvoyant ceiling (ours; README), shares [0-1]
QUALITY: tuple[Metric, ...] = (
    ("held", "held_share", "share of the detectable steps held: confirmed within metrics.gate of the truth"),
    ("false_track", "false_track_share", "share of the detectable steps with a confirmed track further off"),
    ("missed", "missed_share", "share of the detectable steps without a confirmed track"),
    ("ceiling", "ceiling_share", "clairvoyant chaser's share of the detectable steps within 8 m of the target"),
)
# (column stem, key of a trial record: 1 yes, 0 no, NaN does not apply, meaning): counted over
# the trials where it applies, with a Clopper-Pearson 95% interval on the share
Count = tuple[str, str, str]
COUNTS: tuple[Count, ...] = (
    ("reacquired", "reacquired_after_last_spell",
     "trials held again after their last undetectable spell, of the trials with such a spell"),
)
TIMING: tuple[Metric, ...] = (
    ("step_s", "step_s_mean", "wall time per simulation step [s]"),
    ("solve_s", "solve_s_mean", "wall time of the control solver per step [s]"),
)
CONFIG_COLUMNS = ("config", "label", "n_controls", "opening_angle_deg", "constraints", "solver")
# figures a trial leaves NaN where they do not apply: the track-quality shares of a trial without
# a detectable step (of a swarm cell without a detectable target, or one downed before it was
# held) and the swarm's time to down, when no target was downed. Each gets a column ``STEM_trials``
# in summary.csv and paired.csv: the number of trials its mean, or its paired difference, is over
WHERE_DEFINED = frozenset({
    "held_share", "false_track_share", "missed_share", "ceiling_share",  # QUALITY
    "held50_share", "held_airborne_share", "ceiling50_share",  # the swarm's (experiments/swarm.py)
    "downed_step_mean",
})
RECORD_KEYS = tuple(k for _, k, _ in METRICS + TIMING)


# ---------------------------------------------------------------------------------------------
# one trial <-> one Parquet file


def trial_filename(config: int, trial: int) -> str:
    return f"c{config:02d}-t{trial:04d}.parquet"


def record_table(record: Mapping[str, Any]) -> pa.Table:
    """One trial as a one-row table: every number of the record as a float column (those of
    :data:`RECORD_KEYS` first, in order), per-agent incidents as a list, each 1-D numeric
    per-step series ``name`` of the run as a list column ``step.name``, and each per-target list
    ``name`` of a run with several targets (``targets``) as ``target.name``."""
    columns: dict[str, pa.Array] = {
        "experiment": pa.array([str(record["experiment"])]),
        "config": pa.array([int(record["config"])], pa.int64()),
        "trial": pa.array([int(record["trial"])], pa.int64()),
        "seed": pa.array([int(record["seed"])], pa.int64()),
    }
    if "scenario" in record:  # the fingerprint of the trial's settings (engine.scenario_digest)
        columns["scenario"] = pa.array([str(record["scenario"])])
    figures = [k for k, v in record.items() if k not in columns and isinstance(v, (int, float)) and not isinstance(v, bool)]
    for key in sorted(figures, key=lambda k: (k not in RECORD_KEYS, RECORD_KEYS.index(k) if k in RECORD_KEYS else 0, k)):
        columns[key] = pa.array([float(record[key])], pa.float64())
    columns["jamming_incidents"] = pa.array([[int(v) for v in record.get("jamming_incidents", [])]], pa.list_(pa.int64()))
    for name, values in sorted((record.get("steps") or {}).items()):
        a = np.asarray(values)
        if a.ndim == 1 and a.dtype.kind in "biuf":
            columns[f"step.{name}"] = pa.array([a.astype(float).tolist()], pa.list_(pa.float64()))
    for name, values in sorted((record.get("targets") or {}).items()):
        columns[f"target.{name}"] = pa.array([[float(v) for v in values]], pa.list_(pa.float64()))
    return pa.table(columns)


def write_trial(folder: Path, record: Mapping[str, Any]) -> Path:
    """Write a trial atomically (:func:`trackjam.files.atomic_write`)."""
    final = folder / trial_filename(int(record["config"]), int(record["trial"]))

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:  # a file object: pyarrow's own path handling refuses a name that is not UTF-8
            pq.write_table(record_table(record), fh)

    return atomic_write(final, write)


class DamagedTrial(ValueError):
    """A trial file that cannot be read back whole (truncated, empty, or not a trial record)."""


_IDENTITY = (("experiment", str), ("config", int), ("trial", int), ("seed", int))


# the values a trial file may hold (its footer counts them before they are read): the largest
# ours write, 100,000 steps of 20 per-step series, hold 2 million; a file of a few kB can hold
# billions of zeros (run-length encoded), gigabytes once read
TRIAL_MAX_VALUES = 20_000_000
# the largest figure a trial file may hold: far past any a trial yields (powers of 64 agents at
# 1 MW, 100,000 steps, wall times), and small enough that the summary's sums and squares of
# 20,000 trials (MAX_TRIAL_RUNS) stay finite; a hand-edited 1e308 gave inf in summary.csv and
# numpy's overflow warnings
TRIAL_MAX_FIGURE = 1e100


# the figures no trial can make negative (powers, incidents, errors, times, steps, rates); a
# figure ``*_share`` lies in [0, 1] and a count of COUNTS is 0 or 1. A figure of another name (a
# new experiment's) is only held to TRIAL_MAX_FIGURE.
NONNEGATIVE = frozenset({
    "jamming_incidents_per_agent", "target_received_w_mean", "agent_received_w_mean", "transmit_w_mean",
    "ospa_mean", "ospa_card_mean", "false_tracks_per_step", "downed_step_mean", "step_s_mean", "solve_s_mean",
})
COUNT_KEYS = frozenset(k for _, k, _ in COUNTS)


def figure_problem(key: str, value: float) -> str | None:
    """What is wrong with figure ``key`` of a trial record (None: nothing; NaN, a figure that does
    not apply, is fine): outside [0, 1] for a share, not 0 or 1 for a count, negative for a
    figure in :data:`NONNEGATIVE` (a hand-edited OSPA of -1e50 or a held share of 7.5 went into
    summary.csv)."""
    if math.isnan(value):
        return None
    if key.endswith("_share") and not -1e-12 <= value <= 1.0 + 1e-12:
        return f"{key} {value:g} is not a share in [0, 1]"
    if key in COUNT_KEYS and value not in (0.0, 1.0):
        return f"{key} {value:g} is not 0 or 1"
    if key in NONNEGATIVE and value < 0.0:
        return f"{key} {value:g} is negative"
    return None


def read_trial(path: Path, keys: tuple[str, ...] = RECORD_KEYS) -> dict:
    """The record in one trial file; :class:`DamagedTrial` if it is not a complete one (one
    row, the identity columns and the figures ``keys``, each NaN or within
    +-:data:`TRIAL_MAX_FIGURE` and in its range, :func:`figure_problem`) or holds more than
    :data:`TRIAL_MAX_VALUES` values."""
    try:
        with open(path, "rb") as fh:  # a file object, as write_trial's
            meta = pq.read_metadata(fh)
            values = sum(meta.row_group(g).column(c).num_values
                         for g in range(meta.num_row_groups) for c in range(meta.num_columns))
            if values <= TRIAL_MAX_VALUES:
                table = pq.read_table(fh)
    except (pa.ArrowException, OSError, ValueError) as err:
        raise DamagedTrial(f"{path.name}: {type(err).__name__}") from None
    if values > TRIAL_MAX_VALUES:
        raise DamagedTrial(f"{path.name}: {values:,} values, larger than a trial ({TRIAL_MAX_VALUES:,} at most)")
    missing = [k for k, _ in _IDENTITY if k not in table.column_names]
    missing += [k for k in keys if k not in table.column_names]
    if table.num_rows != 1 or missing:
        raise DamagedTrial(f"{path.name}: {table.num_rows} rows, missing {missing}")
    record = table.to_pylist()[0]
    if any(not isinstance(record[k], kind) for k, kind in _IDENTITY):
        raise DamagedTrial(f"{path.name}: a null or mistyped identity column")
    if any(isinstance(record[k], bool) or not isinstance(record[k], (int, float)) for k in keys):
        raise DamagedTrial(f"{path.name}: a null or mistyped figure")  # the summary's means would fail on it
    if any(math.isinf(record[k]) for k in keys):  # no trial yields one (NaN: a figure that does not apply)
        raise DamagedTrial(f"{path.name}: an infinite figure")
    if any(abs(record[k]) > TRIAL_MAX_FIGURE for k in keys):  # NaN compares False: it stays
        raise DamagedTrial(f"{path.name}: a figure past +-{TRIAL_MAX_FIGURE:g}, larger than any trial yields")
    if problems := [p for k in keys if (p := figure_problem(k, float(record[k])))]:
        raise DamagedTrial(f"{path.name}: {problems[0]}, which no trial yields")
    return record


_TRIAL_NAME = re.compile(r"^c(\d{2,})-t(\d{4,})\.parquet$")


def parse_trial_filename(name: str) -> tuple[int, int] | None:
    """(config, trial) of a name :func:`trial_filename` writes, else None."""
    m = _TRIAL_NAME.match(name)
    if m is None:
        return None
    key = int(m[1]), int(m[2])
    return key if trial_filename(*key) == name else None


# ---------------------------------------------------------------------------------------------
# tables


def mean_ci95(values: Iterable[float]) -> tuple[float, float]:
    """Sample mean and the half-width of its t-based 95% confidence interval,
    t_{0.975, n-1} s / sqrt(n) (NaN for fewer than 2 values)."""
    x = np.asarray(list(values), dtype=float)
    n = len(x)
    if n == 0:
        return math.nan, math.nan
    m = float(x.mean())
    if n < 2:
        return m, math.nan
    # values equal but for rounding (b - a of shares like 1/3 - 2/3 and 2/3 - 1) vary by 0, not 1e-16
    s = 0.0 if np.ptp(x) <= 1e-12 * float(np.abs(x).max()) else float(x.std(ddof=1))
    return m, float(stats.t.ppf(0.975, n - 1) * s / math.sqrt(n))


def _fmt(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "" if math.isnan(v) else format(v, ".6g")
    return str(v)


def count_ci95(values: Iterable[float]) -> tuple[int, int, float, float]:
    """(k, n, low, high): k trials of the n where the value is not NaN have it 1, and the
    Clopper-Pearson 95% interval on the share k / n (NaN bounds when n = 0)."""
    x = np.asarray([math.nan if v is None else v for v in values], dtype=float)
    x = x[~np.isnan(x)]
    k, n = int(np.sum(x == 1)), len(x)
    if n == 0:
        return 0, 0, math.nan, math.nan
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return k, n, float(ci.low), float(ci.high)


def _defined(v: Any) -> bool:
    """A trial's figure that applies: neither None nor NaN."""
    return v is not None and not math.isnan(v)


def table_rows(
    records: list[Mapping[str, Any]],
    configurations: list[Mapping[str, Any]],
    metrics: tuple[Metric, ...],
    counts: tuple[Count, ...] = (),
) -> list[dict[str, Any]]:
    """One row per configuration (in order): its parameters (:data:`CONFIG_COLUMNS`, then any
    other key of the configuration), trials, mean/ci95 of each metric over the trials where it
    is defined (not NaN; records are taken in trial order, whatever order they finished), with,
    for a metric of :data:`WHERE_DEFINED`, ``STEM_trials``: how many those are; and for each
    count ``STEM`` (k), ``STEM_of`` (n), ``STEM_lo`` and ``STEM_hi`` (:func:`count_ci95`).
    A NaN is left out as :func:`paired_rows` leaves it out: a share of a trial without a
    detectable step made the whole configuration's mean NaN (an empty cell), while its paired
    differences were over the other trials."""
    rows = []
    for conf in configurations:
        mine = sorted((r for r in records if int(r["config"]) == conf["config"]), key=lambda r: int(r["trial"]))
        row = {k: conf[k] for k in CONFIG_COLUMNS}
        row |= {k: v for k, v in conf.items() if k not in row}
        row["trials"] = len(mine)
        for stem, key, _ in metrics:
            values = [r[key] for r in mine if _defined(r[key])]
            row[f"{stem}_mean"], row[f"{stem}_ci95"] = mean_ci95(values)
            if key in WHERE_DEFINED:
                row[f"{stem}_trials"] = len(values)
        for stem, key, _ in counts:
            row[stem], row[f"{stem}_of"], row[f"{stem}_lo"], row[f"{stem}_hi"] = count_ci95(r[key] for r in mine)
        rows.append(row)
    return rows


Pair = tuple[int, int, str]  # (configuration a, configuration b, what b - a compares)


def paired_rows(records: list[Mapping[str, Any]], pairs: Iterable[Pair], metrics: tuple[Metric, ...],
                counts: tuple[Count, ...] = ()) -> list[dict[str, Any]]:
    """One row per pair (a, b, label): ``trials`` both ran, and for each metric ``STEM_diff``, the
    mean over those trials of b's value minus a's (trials where either lacks it, NaN, left out),
    ``STEM_ci95``, the half-width of its t-based 95 % interval: a paired comparison; and for a
    metric of :data:`WHERE_DEFINED`, ``STEM_trials``: the trials both define, the differences'
    number (as :func:`table_rows` states each configuration's). For each count ``STEM`` the
    sign test of the pair (:func:`sign_test`): ``STEM_gained`` and ``STEM_lost``, the trials
    where b has it and a not and the reverse, and ``STEM_p``, the two-sided p-value."""
    by = {(int(r["config"]), int(r["trial"])): r for r in records}
    rows = []
    for a, b, label in pairs:
        trials = sorted(k for c, k in by if c == a and (b, k) in by)
        row: dict[str, Any] = {"a": a, "b": b, "label": label, "trials": len(trials)}
        for stem, key, _ in metrics:
            d = [float(by[(b, k)][key]) - float(by[(a, k)][key]) for k in trials
                 if _defined(by[(a, k)][key]) and _defined(by[(b, k)][key])]
            row[f"{stem}_diff"], row[f"{stem}_ci95"] = mean_ci95(d)
            if key in WHERE_DEFINED:
                row[f"{stem}_trials"] = len(d)
        for stem, key, _ in counts:
            both = [(by[(a, k)][key], by[(b, k)][key]) for k in trials]
            row[f"{stem}_gained"], row[f"{stem}_lost"], row[f"{stem}_p"] = sign_test(both)
        rows.append(row)
    return rows


def sign_test(pairs: Iterable[tuple[Any, Any]]) -> tuple[int, int, float]:
    """(gained, lost, p) of paired yes/no outcomes (a, b), 1 yes, 0 no, NaN or None where it does
    not apply (such pairs are left out): ``gained`` pairs have b and not a, ``lost`` a and not b,
    and ``p`` is the exact two-sided binomial p-value of gained against lost at 1/2 (NaN when
    both are 0: the two never differ)."""
    gained = lost = 0
    for a, b in pairs:
        if not (_defined(a) and _defined(b)):
            continue
        gained += int(b == 1 and a != 1)
        lost += int(a == 1 and b != 1)
    if gained + lost == 0:
        return 0, 0, math.nan
    return gained, lost, float(stats.binomtest(gained, gained + lost, 0.5).pvalue)


def write_table(path: Path, rows: list[dict[str, Any]]) -> None:
    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(list(rows[0]))
            for row in rows:
                w.writerow([_fmt(v) for v in row.values()])

    atomic_write(path, write)


def read_table(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))
