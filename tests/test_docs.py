"""The README documents every configuration key, and CI runs the README's test command."""

import os
import re
from pathlib import Path
import typing

import pytest
from pydantic import BaseModel

from trackjam.config import Scenario

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _keys(model: type[BaseModel], prefix: str = "") -> list[str]:
    out = []
    for name, field in model.model_fields.items():
        key = prefix + name
        out.append(key)
        for a in [field.annotation, *typing.get_args(field.annotation)]:
            if isinstance(a, type) and issubclass(a, BaseModel):
                out += _keys(a, key + ".")
    return out


def test_every_configuration_key_is_in_the_readme_with_a_description():
    missing = [k for k in _keys(Scenario) if f"| `{k}` |" not in README]
    assert not missing, f"README lacks: {missing}"


def test_ci_runs_the_readmes_test_command_exactly():
    first_block = README.split("```bash", 1)[1].split("```", 1)[0].strip().splitlines()
    assert len(first_block) == 2  # exactly two set-up commands open the README
    install_run, install_test = first_block
    assert "trackjam run" in install_run and "pytest" in install_test
    assert install_test in (ROOT / ".ci" / "run").read_text().splitlines()


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*]", "", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(text: str) -> set[str]:
    return {_slug(h) for h in re.findall(r"^#{1,6} (.+)$", _outside_code(text), re.M)}


def _outside_code(text: str) -> str:
    return re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)


DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def test_the_slug_rule_gives_githubs_anchors():
    assert _slug("Experiments (Table I / Fig. 4, Fig. 5)") == "experiments-table-i--fig-4-fig-5"
    assert _slug("The cue's velocity") == "the-cues-velocity"
    assert _slug("Several targets (building blocks, ours)") == "several-targets-building-blocks-ours"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_and_anchor_in_the_docs_resolves(doc):
    """A link to a file of the repository names one that exists, and a #part names one of its
    headings: moving a section from the README to docs/ must move its links too."""
    text = _outside_code(doc.read_text())
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target):  # https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        file = (doc.parent / path).resolve() if path else doc
        if not file.exists():
            broken.append(f"{target}: no file {path}")
        elif anchor and file.suffix == ".md" and anchor not in _anchors(file.read_text()):
            broken.append(f"{target}: no heading #{anchor} in {file.name}")
    assert not broken, broken


def test_the_docs_name_every_option_the_swarm_engine_refuses():
    """The README's and the several-target guide's lists of the options the swarm engine refuses
    name every key it refuses (`filter.mode` was refused and listed in neither)."""
    import trackjam
    from trackjam.simulation.build import _swarm_unsupported

    keys = [key for key, _, _ in _swarm_unsupported(trackjam.load_scenario("swarm-3"))]
    readme = README.split("which does not simulate every option yet", 1)[1].split("`validate` refuses", 1)[0]
    guide = (ROOT / "docs" / "several-targets.md").read_text()
    guide = guide.split("Options the swarm engine\ndoes not simulate yet", 1)[1].split("\n\n", 1)[0]
    assert [k for k in keys if f"`{k}" not in readme] == []
    assert [k for k in keys if f"`{k}" not in guide] == []
    # the comms faults are simulated with several targets now, and neither list names them
    assert "comms" not in readme and "comms" not in guide


def test_the_reacquisition_figure_is_drawn_from_the_committed_oracles_run(tmp_path, monkeypatch):
    """docs/reacquisition.py reads the oracles experiment's summary.csv and paired.csv (the
    committed run in docs/experiments/oracles) and draws one bar per row."""
    import importlib.util

    import matplotlib.pyplot as plt

    from trackjam.experiments.definitions import ORACLE_VARIANTS
    from trackjam.experiments.summary import read_table

    folder = ROOT / "docs" / "experiments" / "oracles"
    assert [r["label"] for r in read_table(folder / "summary.csv")] == [label for label, _ in ORACLE_VARIANTS]
    spec = importlib.util.spec_from_file_location("reacquisition", ROOT / "docs" / "reacquisition.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    drawn = []
    real_savefig = plt.Figure.savefig

    def keep(fig, *args, **kwargs):
        drawn.append(len(fig.axes[0].patches))  # the bars
        return real_savefig(fig, *args, **kwargs)

    monkeypatch.setattr(plt.Figure, "savefig", keep)
    module.main(folder, tmp_path / "reacquisition.png")
    assert drawn == [len(ORACLE_VARIANTS)]
    assert (tmp_path / "reacquisition.png").stat().st_size > 10_000


def test_the_search_reference_runs_on_a_seed_and_its_figure_is_drawn_from_the_committed_table(tmp_path, monkeypatch):
    """docs/search_ceiling.py: one seed's row (the team's run and the four searchers, small), and
    the figure from the committed docs/experiments/search/first_detection.csv, one curve per
    searcher and the team."""
    import importlib.util

    import matplotlib.pyplot as plt

    spec = importlib.util.spec_from_file_location("search_ceiling", ROOT / "docs" / "search_ceiling.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setattr(module, "PARTICLES", 100)
    monkeypatch.setattr(module, "ITERATIONS", 10)
    threads = os.environ.get("NUMBA_NUM_THREADS")
    row = module.one(3)
    assert os.environ.get("NUMBA_NUM_THREADS") == threads  # it runs in the test's process: no numba reset
    assert set(row) == set(module.COLUMNS) and row["last_seen"] == 13
    for v in ("team", *module.VARIANTS):
        assert row[f"{v}_first"] is None or 18 <= row[f"{v}_first"] <= 30
        assert 0.0 <= row[f"{v}_chance"] <= 1.0
    table = ROOT / "docs" / "experiments" / "search" / "first_detection.csv"
    rows = module.read(table)
    assert len(rows) >= 300 and [int(r["seed"]) for r in rows] == list(range(1, len(rows) + 1))
    drawn = []
    real_savefig = plt.Figure.savefig

    def keep(fig, *args, **kwargs):
        drawn.append(len(fig.axes[0].lines))
        return real_savefig(fig, *args, **kwargs)

    monkeypatch.setattr(plt.Figure, "savefig", keep)
    module.figure(table, tmp_path / "search.png")
    assert drawn == [1 + len(module.VARIANTS) + 1 + 2]  # the team, the searchers, the team-like one, two levels
    assert (tmp_path / "search.png").stat().st_size > 10_000
    lines = module.summary(rows)
    assert lines[0].startswith("team: ") and len(lines) == 2 + len(module.VARIANTS)
    ablations = module.read(module.ABLATION_TABLE)  # the same seeds and the same team, the searcher weakened
    assert [r["seed"] for r in ablations] == [r["seed"] for r in rows]
    assert [r["team_first"] for r in ablations] == [r["team_first"] for r in rows]
    assert list(ablations[0]) == list(module.columns(module.ABLATIONS))
    assert len(module.summary(ablations, module.ABLATIONS)) == 2 + len(module.ABLATIONS)


def test_the_report_threshold_rescoring_gives_each_runs_own_quality_at_the_presets_threshold():
    """docs/report_threshold.py: the logs of a run (small), scored at the preset's threshold 0.5,
    give the run's own held and false-track shares, re-acquisition and mean OSPA (the report does
    not feed back); a lower threshold only adds reports. The committed log covers its seeds and
    reproduces the docs' preset rows."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("report_threshold", ROOT / "docs" / "report_threshold.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for seed in (3, 5):
        rows, summary = module.one(seed, filter__particles=1500, filter__birth_particles=300, steps=22)
        assert [r["t"] for r in rows] == list(range(1, 23))
        at_half = module.score(rows, 0.5)
        assert at_half["held"] == summary["held_share"] and at_half["false_track"] == summary["false_track_share"]
        assert at_half["reacquired"] == summary["reacquired_after_last_spell"]
        assert at_half["ospa"] == pytest.approx(summary["ospa_mean"], abs=1e-12)
        assert [r["reported"] for r in rows] == [r["existence"] > 0.5 and r["seen"] > 0.5 and r["spread_m"] <= 8
                                                 for r in rows]
        lower = module.score(rows, 0.2)
        assert lower["held"] >= at_half["held"] and lower["false_track"] >= at_half["false_track"]
        assert lower["reacquired"] >= at_half["reacquired"]
    logged = module.read_log(1, 10**6)
    assert sorted(logged) == list(range(1, 451)) and all(len(v) == 30 for v in logged.values())
    table = module.table({s: logged[s] for s in range(1, 151)})
    assert table[3] == "| 0.5 (the preset) | 56.4 % | 3.2 % | 45 of 150 | 4.43 |"
    assert len(table) == 3 + len(module.THRESHOLDS)


def test_the_faster_agents_runs_are_reproduced_and_give_the_docs_tables(tmp_path):
    """docs/faster_agents.py: a committed run reruns to the same row, and its two tables, drawn
    from the committed runs, are the ones docs/holding.md shows ("Faster agents")."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("faster_agents", ROOT / "docs" / "faster_agents.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    runs = module.read()
    assert sorted(runs) == sorted(module.VARIANTS)
    for variant, rows in runs.items():
        first, last = module.SEEDS.get(variant, (1, 300))
        assert sorted(rows) == list(range(first, last + 1)), variant
    for job in ((2, "7 m, close_in 0.05"), (3, "7 m")):
        assert module.one(job) == runs[job[1]][job[0]]
    assert runs["7 m, close_in 0.05"][2]["closed_steps"] > 0 and runs["7 m"][3]["closed_steps"] == 0
    holding = (ROOT / "docs" / "holding.md").read_text()
    lines = module.summary(runs) + module.table(runs)
    assert [line for line in lines if line not in holding] == []
    assert module.figure(runs, tmp_path / "faster.png").stat().st_size > 10_000


def test_the_readmes_example_of_a_scenario_too_large_gives_its_figure():
    """The figure is counted from the configuration alone (the machine's memory only decides
    whether it is refused, and no machine has 8 TB): the README's quoted message had gone stale
    when the count grew."""
    from trackjam.config import load_scenario
    from trackjam.errors import ConfigError

    quoted = re.search(r"`(agents\.n_inclination: a run would hold about [\d.]+ TB of memory), more than", README)
    assert quoted
    with pytest.raises(ConfigError) as err:
        load_scenario("paper-fig3", ["agents.n_inclination=360", "agents.n_azimuth=360"])
    assert quoted.group(1) in str(err.value)


@pytest.mark.parametrize("script, folder, section", [
    ("search_options", "search-options", "## The small options together"),
    ("birth_mixed", "birth-mixed", "## The mixed birth kept inside the area"),
])
def test_a_paired_table_of_docs_holding_is_the_committed_run_of_its_script(script, folder, section):
    """docs/search_options.py's experiment made docs/experiments/search-options/, and the table of
    docs/holding.md ("The small options together") quotes its counts; likewise docs/birth_mixed.py's."""
    import importlib.util

    from trackjam.experiments.summary import read_table

    spec = importlib.util.spec_from_file_location(script, ROOT / "docs" / f"{script}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    experiment = module.experiment()
    folder = ROOT / "docs" / "experiments" / folder
    rows = read_table(folder / "summary.csv")
    assert [r["label"] for r in rows] == [c.label for c in experiment.configurations]
    assert all(int(r["trials"]) == module.TRIALS for r in rows)
    (pair,) = read_table(folder / "paired.csv")
    preset, together = (int(r["reacquired"]) for r in rows)
    gained, lost = int(pair["reacquired_gained"]), int(pair["reacquired_lost"])
    assert together - preset == gained - lost  # the sign test counts the same trials
    text = (ROOT / "docs" / "holding.md").read_text().split(section, 1)[1].split("\n## ", 1)[0]
    assert f"{preset} of 300" in text and f"{together} of 300" in text and f"{gained} / {lost}" in text


def test_docs_input_names_every_warning_a_scenario_can_give():
    """docs/input.md's list of suspicious but legal values names the key of every warning
    (`comms.delay_steps`, `control.belief_at_least` and `control.belief_spread` warned and were
    listed nowhere)."""
    import trackjam
    from trackjam.config.warnings import scenario_warnings

    doc = (ROOT / "docs" / "input.md").read_text()
    doc = doc.split("## Suspicious but legal values", 1)[1].split("\n## ", 1)[0]
    s = trackjam.load_scenario("pursuit", [
        "steps=5", "antenna.opening_angle_deg=1", "target.appears=9", "target.occlusions=[[4, 7], [8, 9]]",
        "agents.initial=[[30, 30, 30], [30, 30, 30], [10, 15, 15]]", "comms.failures=[{agent: 0, step: 9, mode: channel}]",
        "comms.delay_steps=5", "control.plan_over=point", "control.belief_at_least=1", "filter.association_misses=true",
        "fusion.share=posteriors", "filter.team_proposals=true", "metrics.gate=1000", "control.belief_samples=8",
        "control.greedy_aim=own",
    ])
    unseen = trackjam.load_scenario("pursuit", ["target.occlusions=[]", "oracle.follow_up=3"])
    lines = scenario_warnings(s) + scenario_warnings(unseen)
    keys = {re.match(r"([\w.]+)", line).group(1) for line in lines}
    assert len(keys) == 14, lines
    assert sorted(k for k in keys if f"`{k}" not in doc) == []


def _held_by_step():
    import importlib.util

    spec = importlib.util.spec_from_file_location("held_by_step", ROOT / "docs" / "held_by_step.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_held_by_step_counts_are_drawn_from_the_committed_trials_and_agree_with_the_summary(tmp_path):
    """docs/held_by_step.py: steps.csv is the counts of trials.csv, each configuration's
    re-acquisitions in summary.csv are the trials held again after the occlusion, and the shares
    docs/holding.md and the README quote are those of steps.csv."""
    import csv

    h = _held_by_step()
    trials = h.read_csv(h.TRIALS_TABLE)
    steps = h.read_csv(h.TABLE)
    assert len(trials) == len(h.ROWS) * h.TRIALS and steps == h.table(trials)
    with open(h.TABLE.parent / "summary.csv", newline="") as f:
        summary = {int(r["config"]): r for r in csv.DictReader(f)}
    for config in range(1, len(h.ROWS) + 1):
        mine = [r for r in trials if r["config"] == config]
        assert int(summary[config]["reacquired"]) == sum("H" in r["classes"][17:] for r in mine)
        # every trial's row, not a few: the mean of its shares is the summary's, to its 6 figures
        for key, code in (("held", "H"), ("false_track", "F")):
            shares = [r["classes"].count(code) / sum(c in "HFM" for c in r["classes"]) for r in mine]
            assert float(summary[config][f"{key}_mean"]) == float(f"{sum(shares) / len(shares):.6g}"), (config, key)
        reach = [r["chaser_within_8m"].count("1") / sum(c in "01" for c in r["chaser_within_8m"]) for r in mine]
        assert float(summary[config]["ceiling_mean"]) == float(f"{sum(reach) / len(reach):.6g}"), config
        assert all(set(r["classes"][13:17]) <= set("SP") for r in mine)  # the occlusion: never detectable

    def pooled(config, key, first, last):
        rows = [r for r in steps if r["config"] == config and first <= r["t"] <= last]
        return f"{100 * sum(r[key] for r in rows) / sum(r['detectable'] for r in rows):.1f} %"

    section = (ROOT / "docs" / "holding.md").read_text().split("## Step by step", 1)[1].split("\n## ", 1)[0]
    rows = {line.split(" | ")[0].strip("| "): line for line in section.splitlines() if line.startswith("| ")}
    for label, key, span in (("held, steps 1-13 (before the occlusion)", "held", (1, 13)),
                             ("held, steps 18-30 (after it)", "held", (18, 30)),
                             ("false track, steps 1-13", "false_track", (1, 13)),
                             ("false track, steps 18-30", "false_track", (18, 30))):
        cells = [c.strip() for c in rows[label].strip("|").split("|")][1:]
        want = [pooled(c, key, *span) for c in (1, 2, 3)] + ([pooled(1, "chaser_within_8m", *span)] if key == "held"
                                                             else [""])
        assert cells == want, label
    readme = " ".join(README.split())
    assert (f"holds the target on {pooled(3, 'held', 1, 13)} of the trial-steps, where a clairvoyant chaser is "
            f"within 8 m of it on {pooled(1, 'chaser_within_8m', 1, 13)}") in readme
    assert f"after it, on {pooled(3, 'held', 18, 30)} against the chaser's {pooled(1, 'chaser_within_8m', 18, 30)}" in readme
    preset = {k: float(v) for k, v in summary[3].items() if k not in ("label", "solver", "constraints")}
    from scipy.stats import beta

    k, n = int(preset["reacquired"]), int(preset["reacquired_of"])
    lo, hi = beta.ppf(0.025, k, n - k + 1), beta.ppf(0.975, k + 1, n - k)
    assert (f"the preset holds {100 * preset['held_mean']:.1f} ± {100 * preset['held_ci95']:.1f} %, keeps "
            f"{100 * preset['false_track_mean']:.1f} % false tracks, re-acquires {k} of {n} ({100 * k / n:.0f} %; "
            f"Clopper-Pearson {100 * lo:.0f}-{100 * hi:.0f} %) and has a mean OSPA of {preset['ospa_mean']:.2f} ± "
            f"{preset['ospa_ci95']:.2f} m") in readme


def test_the_held_by_step_trials_rerun_to_their_committed_rows(tmp_path, monkeypatch):
    """Trial 0 of each configuration, run again from the current code, gives its rows of
    trials.csv (its class at every step and the chaser's reach); the figure draws."""
    from trackjam.experiments.definitions import EXPERIMENTS
    from trackjam.experiments.engine import run_experiment

    h = _held_by_step()
    monkeypatch.setitem(EXPERIMENTS, h.NAME, h.experiment())
    run_experiment(h.NAME, trials=1, steps=h.STEPS, seed=h.SEED_OF_EXPERIMENT, workers=1, out=tmp_path / "out")
    committed = [r for r in h.read_csv(h.TRIALS_TABLE) if r["trial"] == 0]
    assert h.trial_rows(tmp_path / "out", trials=1) == committed and len(committed) == len(h.ROWS)
    h.draw(h.read_csv(h.TABLE), tmp_path / "figure.png")
    assert (tmp_path / "figure.png").stat().st_size > 10_000
