"""The several-target pages' results are the committed experiment files they were copied from.

docs/several-targets.md (the swarm experiment's table and findings, the fail-safe's tables) and
docs/swarm.md (the two earlier sweeps) copy by hand from docs/experiments/swarm/,
swarm-cv/ and swarm-n2-hover/ (summary.csv, paired.csv, timing.csv; for swarm/ also the trial
files). Each printed number is held to its file's value within the rounding of the digits
printed (the rule of tests/test_readme_results.py), so a number edited in one place and not the
other fails here. Pure file parsing: nothing is simulated.

Left out, because no committed file holds them (a one-off run, another seed set, a wall time):
- docs/swarm.md, "The velocity cue on swarm-3": its table and every number of its prose (seeds
  1-400 of `trackjam run swarm-3`, the clairvoyant ceiling on those truths, the lead and
  team_objective trials), and the same numbers repeated in several-targets.md's section of that
  name;
- several-targets.md's run of `swarm-3` seed 1 (held by tests/test_readme_code.py against a run),
  its times per step, and its "Seeds 1-20" table and the seeds 1-40 prose after it (runs outside
  docs/experiments);
- the fail-safe section's runs with `filter.response=null`, hedges and targets without a
  fail-safe: every "without" side and paired difference of the "Measured" table, the hedge table
  but for its no-hedge landing cells (which are the swarm experiment's own trials, held below),
  the +1.5, +22.1, +35.0, ... differences, the old b2980fa figures, and swarm.md's "21-36 points";
- the sweeps' wall times and CPU seconds (16 min 19 s, 20 min 59 s, 9 min 33 s, 29 min 58 s,
  1,149 s, ...), the idle rerun of swarm-cv (47 %, 42 %), the earlier swarm run replaced by the
  current one (its 71 and 69 %, +5.5 ± 9.3);
- swarm-cv's per-downing shares (153 downed targets, 86 %, 49 %, 44 %; several-targets.md's
  86 % and 49 % too) and the n = 1/search against n = 2/hover paired differences (+13 ± 9, ...):
  they were computed from swarm-cv's and swarm-n2-hover's trial files, which are not committed;
- "about 10 points held, 1 m OSPA" of the first sweep (approximate);
"""

from __future__ import annotations

import csv
import math
import re
import statistics
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from readme_tables import NUM, differs_from_rounded, table_at, table_start

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
EXPERIMENTS = DOCS / "experiments"
PAGES = {"several-targets.md": (DOCS / "several-targets.md").read_text(),
         "swarm.md": (DOCS / "swarm.md").read_text()}


@cache
def _csv(folder: str, name: str) -> tuple[dict[str, str], ...]:
    with open(EXPERIMENTS / folder / f"{name}.csv", newline="") as f:
        return tuple(csv.DictReader(f))


# --- numbers as printed: the rule of tests/test_readme_results.py ------------------------------

_differs = differs_from_rounded


# the scale each metric is printed at: shares in % (their differences in points), times in ms
SCALE = {"held": 100, "held50": 100, "held_airborne": 100, "ceiling": 100, "ceiling50": 100, "downed": 100,
         "missed": 100, "step_s": 1000, "solve_s": 1000}


# --- the sweep tables, cell by cell ------------------------------------------------------------

COLUMNS = {  # the page's column -> summary.csv's metric (timing.csv's for the step)
    "held": "held",
    "held while airborne": "held_airborne",
    "held >= 50 %": "held50",
    "ceiling": "ceiling",
    "ceiling >= 50 %": "ceiling50",
    "OSPA [m]": "ospa",
    "downed": "downed",
    "time to down [step]": "time_to_down",
    "false tracks / step": "false_tracks",
    "incidents / agent": "incidents",
    # wall time per step inside a worker, timing.csv's step_s_mean in whole ms: that run's, under
    # the load the page states, but committed, so held like the README's step column
    "step [ms]": "step_s",
}
KEYS = {"K": "targets", "N": "agents", "engine": "engine"}


@dataclass(frozen=True)
class Table:
    page: str
    anchor: str  # text that introduces the table: the table is the first one after it
    folder: str


TABLES = [
    Table("several-targets.md", "`swarm.png`). The sweep ran in **16 min 19 s** wall", "swarm"),
    Table("swarm.md", "`docs/experiments/swarm-cv/`: `summary.csv`, `paired.csv`", "swarm-cv"),
    Table("swarm.md", "`docs/experiments/swarm-n2-hover/`: `summary.csv`, `paired.csv`", "swarm-n2-hover"),
]
# The other tables of the two pages, by their header line: held in part by QUOTES below, or left
# out with the reason.
PARTLY_HELD = {
    # the no-hedge landing cells are swarm/'s own trials; the rest are runs outside docs/experiments
    "| filters | K = 3, N = 5, landing targets | K = 3, N = 5, targets without a fail-safe |",
    # the "with" side is swarm/'s own trials; the "without" side and the differences are not committed
    "| cell | engine | held | held >= 50 % | held while airborne | OSPA [m] |",
}
HELD_WHOLE = {
    # the comms faults' table: docs/swarm_comms.py's own lines from experiments/swarm-comms/runs.csv
    # (test_the_comms_faults_table_is_what_its_script_prints_from_its_csv)
    "| fault (seeds 1-",
}
LEFT_OUT = {
    "| `swarm-3` with | held a | held b | held c | all |",  # seeds 1-20 of `trackjam run`, not committed
    "| `swarm-3` | held a | held b | held c | mean |",  # the velocity cue, seeds 1-100, not committed
    "| column | meaning |",  # the output files' columns, not results
}


def _table_start(table: Table) -> int:
    return table_start(PAGES[table.page], table.anchor, table.page)


def _table_rows(table: Table) -> tuple[list[str], list[list[str]]]:
    return table_at(PAGES[table.page], table.anchor, table.page)


def test_every_table_of_the_pages_is_held_or_left_out_by_name():
    """A table added to these pages must be added here (to TABLES, or PARTLY_HELD and QUOTES, or
    LEFT_OUT with the reason)."""
    for page, text in PAGES.items():
        lines = text.split("\n")
        offsets = [sum(len(line) + 1 for line in lines[:i]) for i in range(len(lines))]
        starts = [offsets[i] for i, line in enumerate(lines)
                  if line.startswith("|") and not (i and lines[i - 1].startswith("|"))]
        held = {_table_start(t) for t in TABLES if t.page == page}
        named = PARTLY_HELD | HELD_WHOLE | LEFT_OUT
        unclaimed = [text[s:].split("\n", 1)[0] for s in starts
                     if s not in held and not any(text[s:].startswith(h) for h in named)]
        assert not unclaimed, f"{page}: tables neither held nor left out: {unclaimed}"


@pytest.mark.parametrize("table", TABLES, ids=lambda t: t.folder)
def test_every_cell_of_the_sweep_table_is_its_csv_value_as_rounded(table):
    header, rows = _table_rows(table)
    unknown = [h for h in header if h not in COLUMNS and h not in KEYS]
    assert not unknown, f"{table.page}, {table.folder} table: columns this test does not know how to hold: {unknown}"
    summary, timing = _csv(table.folder, "summary"), _csv(table.folder, "timing")
    assert len(rows) == len(summary), f"{table.page}, {table.folder} table: {len(rows)} rows, summary.csv {len(summary)}"
    mismatches = []
    for i, row in enumerate(rows):
        assert len(row) == len(header), f"{table.page}, {table.folder} table, row {i + 1}: {len(row)} cells"
        s, t = summary[i], timing[i]
        where = f"{table.page}, table of docs/experiments/{table.folder}/, row {i + 1} ({s['label']})"
        for name, cell in zip(header, row):
            if name in KEYS:
                if cell != s[KEYS[name]]:
                    mismatches.append(f"{where}, column '{name}': page {cell!r}, summary.csv {KEYS[name]} = "
                                      f"{s[KEYS[name]]!r}")
                continue
            metric = COLUMNS[name]
            scale = SCALE.get(metric, 1)
            percent = scale == 100
            m = re.fullmatch(rf"({NUM})(?: ± ({NUM}))?( %)?", cell)
            if not m or bool(m.group(3)) != percent or (m.group(2) is None) != (metric == "step_s"):
                mismatches.append(f"{where}, column '{name}': page {cell!r} is not "
                                  + ("a whole number" if metric == "step_s" else "'mean ± half-width'")
                                  + (" in %" if percent else ""))
                continue
            source, csv_row = ("timing", t) if metric == "step_s" else ("summary", s)
            for printed, key in ((m.group(1), f"{metric}_mean"), (m.group(2), f"{metric}_ci95")):
                if printed is None:
                    continue
                value = float(csv_row[key])
                if _differs(printed, value, scale):
                    scaled = f" (x{scale:g}: {value * scale:.6g})" if scale != 1 else ""
                    mismatches.append(f"{where}, column '{name}': page {printed} ({cell!r}), "
                                      f"{source}.csv {key} = {csv_row[key]}{scaled}")
    assert not mismatches, "page table differs from its CSV:\n" + "\n".join(mismatches)


# --- the numbers quoted in the prose (and in the partly held tables) ---------------------------

@dataclass(frozen=True)
class Slot:
    """One quoted number: ``metric`` of row ``label`` of docs/experiments/``folder``/``csv``.csv
    ("paired": b - a, _diff and _ci95; "summary", "timing": _mean and _ci95). ``sign`` -1 where
    the wording carries the sign ("lowers ... by 20.9")."""
    folder: str
    csv: str
    label: str
    metric: str
    sign: int = 1


def sw(label: str, metric: str) -> Slot:
    return Slot("swarm", "summary", label, metric)


def swp(label: str, metric: str, sign: int = 1) -> Slot:
    return Slot("swarm", "paired", label, metric, sign)


def cv(label: str, metric: str) -> Slot:
    return Slot("swarm-cv", "summary", label, metric)


def ms(folder: str, label: str) -> Slot:
    return Slot(folder, "timing", label, "step_s")


@dataclass(frozen=True)
class Quote:
    """``text`` is the page's wording (whitespace collapsed) with {} where a number stands, "x" or
    "x ± h"; ``slots`` says, in order, where each comes from (None: a number not held, from a
    run outside docs/experiments or of another quote)."""
    page: str
    text: str
    slots: tuple[Slot | None, ...]


ONE = "one-target engine -> swarm engine"
ST, SW = "several-targets.md", "swarm.md"
QUOTES = [
    # the fail-safe the filters expect: the cells that are the swarm experiment's own trials
    Quote(ST, "| `filter.response`, no hedge | {} % | {} % | {} % | {} % |",
          (sw("K=3, N=5", "held"), None, sw("K=1, N=3", "held"), sw("K=1, N=3, one-target engine", "held"))),
    Quote(ST, "False tracks do not rise ({} per step against {} without the hedge",
          (None, sw("K=3, N=5", "false_tracks"))),
    *[Quote(ST, f"| {cell} | {engine} | {{}} -> {{}} %, **{{}}** | {{}} -> {{}} %, **{{}}** | "
                f"{{}} -> {{}} %, {{}} | {{}} -> {{}}, **{{}}** |",
            (None, sw(label, "held"), None, None, sw(label, "held50"), None,
             None, sw(label, "held_airborne"), None, None, sw(label, "ospa"), None))
      for cell, engine, label in (("K = 1, N = 3", "one-target", "K=1, N=3, one-target engine"),
                                  ("K = 1, N = 3", "swarm", "K=1, N=3"), ("K = 3, N = 5", "swarm", "K=3, N=5"))],
    Quote(ST, "With K = 3, N = 5 false tracks fall from {} to {} per step", (None, sw("K=3, N=5", "false_tracks"))),
    Quote(ST, "the share of targets downed is unchanged ({} -> {} %, {})", (None, sw("K=3, N=5", "downed"), None)),
    # the swarm experiment's results
    Quote(ST, "Cost per cell: {} ms per step (K = 1, N = 3) to {} ms (K = 4, N = 6), {}-{} ms on the one-target engine",
          (ms("swarm", "K=1, N=3"), ms("swarm", "K=4, N=6"), None, None)),
    Quote(ST, "(K = 1, N = 3: {} -> {} %, {} paired; K = 3, N = 5: {} -> {} %)",
          (None, sw("K=1, N=3", "held"), None, None, sw("K=3, N=5", "held"))),
    # findings
    Quote(ST, "held {}, {}, {} and {} points at N = 3, 4, 5, 6, OSPA {}, {}, {} and {} m",
          tuple(swp(f"K=1, N={n}: {ONE}", "held") for n in range(3, 7))
          + tuple(swp(f"K=1, N={n}: {ONE}", "ospa") for n in range(3, 7))),
    Quote(ST, "where both engines hold the target on {} % of its steps ({} m against {} m)",
          (sw("K=1, N=5", "held"), sw("K=1, N=5", "ospa"), sw("K=1, N=5, one-target engine", "ospa"))),
    Quote(ST, "where both engines hold the target on {} % of its steps ({} m against {} m)",
          (sw("K=1, N=5, one-target engine", "held"), None, None)),
    Quote(ST, "at K = 3, N = 5 the mean held share is {} % ({} % in the first sweep) and {} % of the targets are "
              "held on at least half their steps ({} %)",
          (sw("K=3, N=5", "held"), cv("K=3, N=5", "held"), sw("K=3, N=5", "held50"), cv("K=3, N=5", "held50"))),
    Quote(ST, "The clairvoyant team's ceiling there is {} %, and it keeps a chaser within 8 m of {} % of the targets",
          (sw("K=3, N=5", "ceiling"), sw("K=3, N=5", "ceiling50"))),
    Quote(ST, "(K = 3, N = 5: {} % against {} %; in the first sweep {} % against {} %)",
          (sw("K=3, N=5", "held"), sw("K=3, N=5", "held_airborne"),
           cv("K=3, N=5", "held"), cv("K=3, N=5", "held_airborne"))),
    Quote(ST, "N = 3 -> 6 holds {} points more at K = 3 (held >= 50 %: {}, OSPA {} m) and {} more at K = 4 "
              "(while airborne {}, downed {}, OSPA {} m)",
          (swp("K=3: N=3 -> N=6", "held"), swp("K=3: N=3 -> N=6", "held50"), swp("K=3: N=3 -> N=6", "ospa"),
           swp("K=4: N=3 -> N=6", "held"), swp("K=4: N=3 -> N=6", "held_airborne"),
           swp("K=4: N=3 -> N=6", "downed"), swp("K=4: N=3 -> N=6", "ospa"))),
    Quote(ST, "at K = 3 the sixth agent alone adds {} points", (swp("K=3: N=5 -> N=6", "held"),)),
    Quote(ST, "At K = 2 the held share while airborne rises ({}) and the OSPA falls ({} m), both significant, "
              "while the held share's {} is not",
          (swp("K=2: N=3 -> N=6", "held_airborne"), swp("K=2: N=3 -> N=6", "ospa"), swp("K=2: N=3 -> N=6", "held"))),
    Quote(ST, "K = 2 -> 3 lowers the held share by {} (N = 3), {} (N = 4) and {} points (N = 5), significant, "
              "and {} at N = 6",
          tuple(swp(f"N={n}: K=2 -> K=3", "held", -1) for n in (3, 4, 5)) + (swp("N=6: K=2 -> K=3", "held"),)),
    Quote(ST, "From K = 1 to K = 4 the held share falls by {}, {}, {} and {} points (N = 3, 4, 5, 6)",
          tuple(swp(f"N={n}: K=1 -> K=4", "held", -1) for n in range(3, 7))),
    Quote(ST, "{} % (N = 3) to {} % (N = 6) at K = 4", (sw("K=4, N=3", "downed"), sw("K=4, N=6", "downed"))),
    # docs/swarm.md, the first sweep
    Quote(SW, "Cost per cell: {} ms per step (K = 1, N = 3) to {} ms (K = 4, N = 6) under that load, {}-{} ms on "
              "the one-target engine", (ms("swarm-cv", "K=1, N=3"), ms("swarm-cv", "K=4, N=6"), None, None)),
]


@dataclass(frozen=True)
class Range:
    """``text`` has two {}, a range's printed ends: the least and the greatest of ``metric`` over
    the rows ``labels`` of docs/experiments/``folder``/``csv``.csv."""
    page: str
    text: str
    folder: str
    csv: str
    metric: str
    labels: tuple[str, ...]


SWARM_CELLS = tuple(f"K={k}, N={n}" for k in range(1, 5) for n in range(3, 7))
ONE_TARGET_CELLS = tuple(f"K=1, N={n}, one-target engine" for n in range(3, 7))


def _cells(k: int) -> tuple[str, ...]:
    return tuple(f"K={k}, N={n}" for n in range(3, 7))


RANGES = [
    Range(ST, "ms (K = 4, N = 6), {}-{} ms on the one-target engine", "swarm", "timing", "step_s", ONE_TARGET_CELLS),
    Range(ST, "and the OSPA rises by {}-{} m, all significant", "swarm", "paired", "ospa",
          tuple(f"N={n}: K=1 -> K=4" for n in range(3, 7))),
    Range(ST, "False tracks grow from {}-{} per step at K = 1", "swarm", "summary", "false_tracks", _cells(1)),
    Range(ST, "per step at K = 1 to {}-{} at K = 4", "swarm", "summary", "false_tracks", _cells(4)),
    Range(ST, "{}-{} % of the targets at K = 1 and 2", "swarm", "summary", "downed", _cells(1) + _cells(2)),
    Range(ST, "{}-{} % at K = 3, 61 %", "swarm", "summary", "downed", _cells(3)),
    Range(ST, "at step {}-{} on average: the response", "swarm", "summary", "time_to_down", SWARM_CELLS),
    Range(SW, "under that load, {}-{} ms on the one-target engine", "swarm-cv", "timing", "step_s", ONE_TARGET_CELLS),
    Range(SW, "The held share while airborne ({}-{} %)", "swarm-cv", "summary", "held_airborne", SWARM_CELLS),
    Range(SW, "the held share over the whole run ({}-{} %)", "swarm-cv", "summary", "held", SWARM_CELLS),
]


def _quoted(page: str, wording: str) -> list[str]:
    """The numbers standing at the {}s, from the one place the page words it so."""
    text = " ".join(PAGES[page].split())
    pattern = rf"({NUM}(?: ± {NUM})?)".join(map(re.escape, wording.split("{}")))
    found = re.findall(pattern, text)
    assert len(found) == 1, f"{page} words {wording!r} {len(found)} times, not once: reworded? update this test's quote"
    return list(found[0]) if isinstance(found[0], tuple) else [found[0]]


def _value(folder: str, csv_name: str, label: str, metric: str) -> tuple[str, float, float]:
    rows = {r["label"]: r for r in _csv(folder, csv_name)}
    assert label in rows, f"docs/experiments/{folder}/{csv_name}.csv has no row {label!r}"
    row = rows[label]
    key = f"{metric}_diff" if csv_name == "paired" else f"{metric}_mean"
    return key, float(row[key]), float(row[f"{metric}_ci95"])


def _quote_id(q: Quote | Range) -> str:
    return f"{q.page}:{q.text[:56]}"


@pytest.mark.parametrize("quote", QUOTES, ids=_quote_id)
def test_every_number_the_pages_quote_is_its_csv_value_as_rounded(quote):
    printed = _quoted(quote.page, quote.text)
    assert len(printed) == len(quote.slots)
    mismatches = []
    for number, slot in zip(printed, quote.slots):
        if slot is None:
            continue
        mean, _, half = number.partition(" ± ")
        key, value, ci95 = _value(slot.folder, slot.csv, slot.label, slot.metric)
        scale = SCALE.get(slot.metric, 1)
        source = f"docs/experiments/{slot.folder}/{slot.csv}.csv row {slot.label!r}"
        scaled = f" (x{scale:g})" if scale != 1 else ""
        if _differs(mean, value, scale, sign=slot.sign):
            mismatches.append(f"{quote.page}, {quote.text!r}: page {number}, {source} {key} = {value:g}{scaled}"
                              + (" (the wording carries the sign: the page's number is minus it)"
                                 if slot.sign == -1 else ""))
        if half and _differs(half, ci95, scale):
            mismatches.append(f"{quote.page}, {quote.text!r}: page {number}, {source} {slot.metric}_ci95 = "
                              f"{ci95:g}{scaled}")
    assert not mismatches, "page differs from its CSV:\n" + "\n".join(mismatches)


@pytest.mark.parametrize("quote", RANGES, ids=_quote_id)
def test_every_range_the_pages_quote_spans_its_csv_rows(quote):
    low, high = _quoted(quote.page, quote.text)
    values = [_value(quote.folder, quote.csv, label, quote.metric)[1] for label in quote.labels]
    scale = SCALE.get(quote.metric, 1)
    assert not _differs(low, min(values), scale) and not _differs(high, max(values), scale), (
        f"{quote.page}, {quote.text!r}: page {low} to {high}, docs/experiments/{quote.folder}/{quote.csv}.csv "
        f"{quote.metric} over {list(quote.labels)}: {min(values):g} to {max(values):g}"
        + (f" (x{scale:g})" if scale != 1 else ""))


# --- from the swarm experiment's trial files ---------------------------------------------------

def test_the_median_downing_step_is_3_in_every_k3_cell_as_the_trial_files_say():
    """several-targets.md: "the median downing step is 3 in every K = 3 cell" (docs/experiments/
    swarm/trials/, each trial's target.downed_at; the K = 3 cells are configs 9-12)."""
    wording = "the median downing step is 3 in every K = 3 cell"
    assert " ".join(PAGES[ST].split()).count(wording) == 1, f"{ST} no longer words {wording!r}: update this test"
    configs = [int(r["config"]) for r in _csv("swarm", "summary") if r["targets"] == "3" and r["engine"] == "swarm"]
    assert configs == [9, 10, 11, 12]
    for config in configs:
        files = sorted((EXPERIMENTS / "swarm" / "trials").glob(f"c{config:02d}-t*.parquet"))
        assert len(files) == 20, f"docs/experiments/swarm/trials/: {len(files)} trial files of config {config}"
        steps = [d for f in files for d in pq.read_table(f, columns=["target.downed_at"]).column(0).to_pylist()[0]
                 if d is not None and not math.isnan(d)]
        median = statistics.median(steps)
        assert median == 3, f"{ST}, {wording!r}: docs/experiments/swarm/trials/ config {config}: median {median:g}"


def _seed_rows() -> list[dict]:
    with open(DOCS / "experiments" / "swarm-seeds" / "seeds.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def test_swarm3_over_seeds_1_to_400_is_its_csv_wherever_the_pages_quote_it():
    # README, several-targets.md and swarm.md quote docs/swarm_seeds.py's run of seeds 1-400
    from scipy import stats

    rows = _seed_rows()
    assert [int(r["seed"]) for r in rows] == list(range(1, 401))
    quoted = []
    for k in "abc":
        x = [100 * r[f"held_{k}"] for r in rows]
        half = stats.t.ppf(0.975, len(x) - 1) * statistics.stdev(x) / math.sqrt(len(x))
        quoted.append(f"{statistics.fmean(x):.1f} ± {half:.1f} %")
    both = sum(all(r[f"held_{k}"] >= 0.5 for k in "abc") for r in rows)
    ceiling = sum(all(r[f"ceiling_{k}"] >= 0.5 for k in "abc") for r in rows)
    capped = sum(r["capped_steps"] > 0 for r in rows)
    flat = {name: " ".join(text.split()) for name, text in
            (("README", (ROOT / "README.md").read_text()), ("several-targets", (DOCS / "several-targets.md").read_text()),
             ("swarm", (DOCS / "swarm.md").read_text()))}
    line = f"a on {quoted[0]}, b on {quoted[1]} and c on {quoted[2]}"
    for name, text in flat.items():
        assert line in text, (name, line)
    assert f"in {both} of the 400 seeds, where a clairvoyant team reaches that in {ceiling}" in flat["README"]
    assert f"in {both} of the 400 seeds, and even a clairvoyant team reaches that in only {ceiling}" in flat["several-targets"]
    counts = [sum(r[f"held_{k}"] >= 0.5 for r in rows) for k in "abc"]
    assert (f"a is held on at least half its steps in {counts[0]} of the 400 seeds, b in {counts[1]} and c in "
            f"{counts[2]}, and all three in {both}") in flat["swarm"]
    assert f"stops a search on some step in {capped} of the 400 seeds" in flat["swarm"]
    for k, mean in zip("abc", ("78.5", "85.2", "82.4")):  # the ceiling on the same truths
        assert f"{100 * statistics.fmean(r[f'ceiling_{k}'] for r in rows):.1f}" == mean


def test_the_comms_faults_table_is_what_its_script_prints_from_its_csv():
    import importlib.util

    spec = importlib.util.spec_from_file_location("swarm_comms", DOCS / "swarm_comms.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    runs = mod.read_runs()
    assert all(len(x) == 20 for x in runs.values())
    page = (DOCS / "several-targets.md").read_text().split("\n")
    lines = mod.table(runs)
    start = page.index(lines[0])
    assert page[start : start + len(lines)] == lines
