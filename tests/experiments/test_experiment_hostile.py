"""`trackjam experiment` against a hostile user: counts whose plan or pool cannot fit the
machine, options the swarm engine does not read, result names taken by folders. Each is one
line naming the option, before anything is written; a write that fails late keeps what was
written."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from sweep_helpers import ENV, SWEEP

from trackjam.config.limits import MAX_TRIAL_RUNS, WORKER_BYTES, memory_budget
from trackjam.errors import ConfigError, OutputError
from trackjam.experiments.engine import run_experiment
from trackjam.experiments.summary import trial_filename


@pytest.mark.parametrize("trials", [10**12, MAX_TRIAL_RUNS // 2 + 1])
def test_trials_whose_plan_would_not_end_are_refused_before_any_is_built(tmp_path, trials):
    # constraints has 2 configurations: MAX_TRIAL_RUNS / 2 + 1 trials are one run past the cap
    with pytest.raises(ConfigError, match=r"^--trials \d+: [\d,]+ trial runs \(2 configurations") as err:
        run_experiment("constraints", **{**SWEEP, "trials": trials}, workers=1, out=tmp_path / "e")
    assert "lower --trials" in str(err.value)
    assert not (tmp_path / "e").exists()


def test_the_cap_counts_configurations_and_trials():
    from trackjam.config.limits import check_trial_runs

    check_trial_runs(MAX_TRIAL_RUNS // 4, 4)
    with pytest.raises(ConfigError):
        check_trial_runs(MAX_TRIAL_RUNS // 4 + 1, 4)


def test_a_pool_past_the_machine_is_refused_naming_workers(tmp_path):
    too_many = int(memory_budget() // WORKER_BYTES) + 1
    with pytest.raises(ConfigError, match=rf"^--workers {too_many}: .* use at most \d+$"):
        run_experiment("constraints", **SWEEP, workers=too_many, out=tmp_path / "e")
    assert not (tmp_path / "e").exists()


def test_a_trial_function_the_workers_cannot_import_is_refused_before_out_is_written(tmp_path):
    # it was a PicklingError traceback at the first trial, with experiment.json and trials/ written
    from sweep_helpers import fake_trial

    def local(scenario):
        return fake_trial(scenario)

    for trial, shown in ((lambda s: fake_trial(s), "<lambda>"), (local, "local")):
        with pytest.raises(TypeError, match=rf"^trial: {re.escape(shown)} of module \S+ cannot be sent to the workers, which import "
                                            r"it by its module and name: define it at the top level of a module"):
            run_experiment("constraints", **{**SWEEP, "trial": trial}, workers=2, out=tmp_path / "e")
        assert not (tmp_path / "e").exists()
    # one worker is this process: any function runs there
    run_experiment("constraints", **{**SWEEP, "trial": lambda s: fake_trial(s)}, workers=1, out=tmp_path / "one")


def test_a_trial_function_of_an_interactive_session_is_refused_before_out_is_written(tmp_path, monkeypatch):
    # python -c, the REPL or a notebook: the function pickles as __main__.NAME, which no spawned
    # worker can import; it was a worker traceback each and "a worker process of the pool ended
    # abruptly (... perhaps by the system for lack of memory ...)", with experiment.json and trials/ written
    import types

    from sweep_helpers import fake_trial

    def typed_in(scenario):
        return fake_trial(scenario)

    session = types.ModuleType("__main__")  # an interactive __main__: no __file__
    typed_in.__module__, typed_in.__qualname__ = "__main__", "typed_in"
    session.typed_in = typed_in
    monkeypatch.setitem(sys.modules, "__main__", session)
    with pytest.raises(TypeError, match=r"^trial: typed_in of module __main__ cannot be sent to the workers, which "
                                        r"import it by its module and name: this session's __main__ has no file"):
        run_experiment("constraints", **{**SWEEP, "trial": typed_in}, workers=2, out=tmp_path / "e")
    assert not (tmp_path / "e").exists()
    run_experiment("constraints", **{**SWEEP, "trial": typed_in}, workers=1, out=tmp_path / "one")


def test_the_cli_refuses_a_million_workers_in_one_line(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "trackjam", "experiment", "constraints", "--trials", "1", "--steps", "2",
         "--workers", "1000000", "--out", str(tmp_path / "e")],
        capture_output=True, text=True, env=ENV, timeout=120,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("trackjam: error: --workers 1000000:")
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("item, key", [("fusion.existence=evidence", "fusion.existence"),
                                       ("control.close_in=0.1", "control.close_in"),
                                       ("control.plan_over=belief", "control.plan_over")])
def test_an_option_the_swarm_engine_does_not_read_is_refused_before_out_is_claimed(tmp_path, item, key):
    # before: experiment.json and trials/ were written, then every trial failed in its worker
    with pytest.raises(ConfigError, match=rf"^--set {re.escape(item)}: {key}: .* several targets"):
        run_experiment("swarm", grid="2x2", trials=1, steps=2, workers=1, progress="none", out=tmp_path / "e",
                       overrides=[item])
    assert not (tmp_path / "e").exists()


@pytest.fixture(scope="module")
def done(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("done")
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    return out


@pytest.mark.parametrize("name", ["summary.csv", "timing.csv", "fig5.png"])
def test_a_result_name_taken_by_a_folder_is_refused_up_front(done, tmp_path, name):
    out = tmp_path / "e"
    shutil.copytree(done, out)
    (out / name).unlink()
    (out / name).mkdir()
    before = {p.relative_to(out): p.stat().st_mtime_ns for p in out.rglob("*")}
    with pytest.raises(ConfigError, match=rf"^--out {out}: {name} is a folder"):
        run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert {p.relative_to(out): p.stat().st_mtime_ns for p in out.rglob("*")} == before


@pytest.mark.parametrize("make", [lambda p: p.mkdir(), os.mkfifo], ids=["folder", "pipe"])
def test_a_trial_file_name_taken_by_a_folder_or_a_pipe_is_refused_before_any_trial_runs(done, tmp_path, make):
    # it was passed over as "not a trial of this experiment", the trial run again, and its write
    # failed once it was done ("trial 0 of configuration 1 cannot be written (Is a directory)")
    out = tmp_path / "e"
    shutil.copytree(done, out)
    slot = out / "trials" / trial_filename(1, 0)
    slot.unlink()
    make(slot)
    before = {p.relative_to(out): p.stat().st_mtime_ns for p in out.rglob("*")}
    with pytest.raises(ConfigError, match=rf"^--out {out}: trials/{slot.name} is a (folder|device or a pipe), "
                                          "not a file; move it away"):
        run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert {p.relative_to(out): p.stat().st_mtime_ns for p in out.rglob("*")} == before


@pytest.mark.parametrize("name, make", [("summary.csv", lambda p: p.symlink_to("/dev/null")),
                                        ("paired.csv", lambda p: os.mkfifo(p))])
def test_a_result_name_taken_by_a_device_or_a_pipe_is_named_so(done, tmp_path, name, make):
    # it was refused as "a folder"
    out = tmp_path / "e"
    shutil.copytree(done, out)
    (out / name).unlink()
    make(out / name)
    with pytest.raises(ConfigError, match=rf"^--out {out}: {name} is a device or a pipe, not a file; move it away"):
        run_experiment("constraints", workers=1, out=out, **SWEEP)


def test_a_summary_that_cannot_be_written_late_is_one_line_and_keeps_the_trials(done, tmp_path, monkeypatch):
    import trackjam.experiments.engine as engine

    out = tmp_path / "e"
    shutil.copytree(done, out)
    kept = (out / "summary.csv").read_bytes()

    def full_disk(path, rows):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(engine, "write_table", full_disk)
    with pytest.raises(OutputError, match=r"summary.csv: cannot be written \(No space left on device\); the trials"):
        run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert (out / "summary.csv").read_bytes() == kept
    assert len(list((out / "trials").iterdir())) == 4


def test_a_trial_that_cannot_be_written_is_one_line_and_keeps_the_others(done, tmp_path, monkeypatch):
    import trackjam.experiments.engine as engine

    out = tmp_path / "e"
    shutil.copytree(done, out)
    last = out / "trials" / trial_filename(2, 1)  # configurations count from 1
    last.unlink()
    write_trial = engine.write_trial

    def late_folder(folder, record):
        # a folder where the trial's file goes, made while the trial ran (one there before the
        # run is refused up front: test_a_trial_file_name_taken_by_a_folder_or_a_pipe_...)
        if (record["config"], record["trial"]) == (2, 1):
            last.mkdir()
        return write_trial(folder, record)

    monkeypatch.setattr(engine, "write_trial", late_folder)
    with pytest.raises(OutputError, match=r"trial 1 of configuration 2 cannot be written \(Is a directory\); the 3 trials"):
        run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert sorted(p.name for p in (out / "trials").iterdir() if p.is_file()) == sorted(
        trial_filename(c, k) for c in (1, 2) for k in (0, 1) if (c, k) != (2, 1))


@pytest.mark.parametrize("value", [pa.array(["abc"]), pa.array([None], type=pa.float64()), pa.array([True]),
                                   pa.array([float("inf")]), pa.array([-float("inf")]), pa.array([1e308]),
                                   pa.array([-1.7976931348623157e308]), pa.array([1.0000001e100])])
def test_a_trial_whose_figure_is_mistyped_is_run_again_not_a_traceback(done, tmp_path, value):
    # an infinite figure (no trial yields one) was read back: inf in summary.csv, numpy's and
    # matplotlib's RuntimeWarnings on stderr
    out = tmp_path / "e"
    shutil.copytree(done, out)
    path = out / "trials" / trial_filename(1, 0)
    table = pq.read_table(path)
    pq.write_table(table.set_column(table.column_names.index("ospa_mean"), "ospa_mean", value), path)
    result = run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert result.ran == 1 and any("damaged" in n and path.name in n for n in result.notes)
    assert (out / "summary.csv").read_bytes() == (done / "summary.csv").read_bytes()


def test_a_link_to_no_file_at_a_trials_name_is_damaged_not_foreign(done, tmp_path):
    # it was said to be "not a trial of this experiment" and left alone, then run and replaced
    out = tmp_path / "e"
    shutil.copytree(done, out)
    path = out / "trials" / trial_filename(2, 1)
    path.unlink()
    path.symlink_to(tmp_path / "gone.parquet")
    result = run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert result.ran == 1 and any("damaged" in n and path.name in n for n in result.notes)
    assert not any("not trials of this experiment" in n for n in result.notes)
    assert path.is_file() and not path.is_symlink()
    assert (out / "summary.csv").read_bytes() == (done / "summary.csv").read_bytes()


def _edit_figure(path: Path, key: str, value: float) -> None:
    table = pq.read_table(path)
    pq.write_table(table.set_column(table.column_names.index(key), key, pa.array([value])), path)


@pytest.mark.parametrize("key, value, words", [
    ("ospa_mean", -1e50, "ospa_mean -1e+50 is negative"),
    ("held_share", 7.5, "held_share 7.5 is not a share in [0, 1]"),
    ("reacquired_after_last_spell", 0.5, "reacquired_after_last_spell 0.5 is not 0 or 1"),
    ("jamming_incidents_per_agent", -5.0, "jamming_incidents_per_agent -5 is negative"),
])
def test_a_hand_edited_figure_no_trial_yields_is_run_again(done, tmp_path, key, value, words):
    # an OSPA of -1e50, a held share of 7.5 and a re-acquisition of 0.5 were read back into
    # summary.csv and paired.csv (a "significant" paired difference of 1e99)
    from trackjam.experiments.summary import DamagedTrial, read_trial

    out = tmp_path / "e"
    shutil.copytree(done, out)
    path = out / "trials" / trial_filename(1, 0)
    _edit_figure(path, key, value)
    with pytest.raises(DamagedTrial, match=re.escape(words)):
        read_trial(path, (key,))
    result = run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert result.ran == 1 and any("damaged" in n and path.name in n for n in result.notes)
    for name in ("summary.csv", "paired.csv"):
        assert (out / name).read_bytes() == (done / name).read_bytes(), name


def test_a_figure_that_does_not_apply_stays_nan():
    from trackjam.experiments.summary import figure_problem

    assert figure_problem("held_share", float("nan")) is None and figure_problem("ospa_mean", 0.0) is None
    assert figure_problem("held_share", 1.0) is None and figure_problem("a_new_gain", -3.0) is None


def test_hand_edited_huge_figures_are_run_again_without_an_overflow(done, tmp_path):
    # 1e308 is finite, so it was read back: the interval's squares and the pairs' differences
    # overflowed (numpy's RuntimeWarnings), and summary.csv and paired.csv held inf
    import warnings

    from trackjam.experiments.engine import summarise_folder
    from trackjam.experiments.summary import TRIAL_MAX_FIGURE, read_table

    out = tmp_path / "e"
    shutil.copytree(done, out)
    _edit_figure(out / "trials" / trial_filename(1, 0), "ospa_mean", 1e308)
    _edit_figure(out / "trials" / trial_filename(2, 1), "held_share", -1e308)
    _edit_figure(out / "trials" / trial_filename(2, 0), "transmit_w_mean", TRIAL_MAX_FIGURE)  # the bound: kept
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        summarised = summarise_folder(out)  # no simulation: the huge ones are passed over, in one line
        assert [n for n in summarised.notes if "damaged" in n] == [
            f"2 damaged trial file(s) in {out / 'trials'} will be run again: "
            f"{trial_filename(1, 0)}, {trial_filename(2, 1)}"]
        for name in ("summary.csv", "paired.csv"):
            cells = [v for row in read_table(out / name) for v in row.values()]
            assert not any("inf" in v for v in cells), name
        result = run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert result.ran == 2
    _edit_figure(out / "trials" / trial_filename(2, 0), "transmit_w_mean",
                 pq.read_table(done / "trials" / trial_filename(2, 0))["transmit_w_mean"][0].as_py())
    assert run_experiment("constraints", workers=1, out=out, **SWEEP).ran == 0
    for name in ("summary.csv", "paired.csv"):
        assert (out / name).read_bytes() == (done / name).read_bytes(), name


@pytest.mark.parametrize(
    "damage, words",
    [
        (lambda out: shutil.rmtree(out / "trials"), "no trials/ folder here"),
        (lambda out: (out / "experiment.json").write_text('{"experiment": "constraints"}'),
         "trials, steps, seed, overrides missing or mistyped"),
        (lambda out: _edit_json(out, grid=5), "grid missing or mistyped"),
        (lambda out: _edit_json(out, trials="2"), "trials missing or mistyped"),
    ],
)
def test_summarising_a_damaged_folder_is_one_line(done, tmp_path, damage, words):
    from trackjam.experiments.engine import summarise_folder

    out = tmp_path / "e"
    shutil.copytree(done, out)
    damage(out)
    with pytest.raises(ConfigError, match=words):
        summarise_folder(out)


def _edit_json(out: Path, **changes) -> None:
    import json

    params = json.loads((out / "experiment.json").read_text())
    (out / "experiment.json").write_text(json.dumps({**params, **changes}))


@pytest.mark.parametrize("name", ["table1", "holding"])
def test_a_list_of_targets_for_a_one_target_experiment_points_to_swarm(tmp_path, name):
    # it said "give either target or targets, not both; `target: null` ...", and --set target is refused
    with pytest.raises(ConfigError, match=rf"^--set targets: experiment {name} draws one target per trial; "
                                          "several targets: trackjam experiment swarm$"):
        run_experiment(name, **SWEEP, workers=1, out=tmp_path / "e", overrides=["targets=[{id: a}, {id: b}]"])
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("steps, shown", [(100_001, "100001"), (10**29, "1" + "0" * 29),
                                          (10**40, "(an integer of more than 30 digits)")])
def test_steps_past_the_scenarios_bound_are_blamed_on_the_option(tmp_path, steps, shown):
    # it said "base scenario of the experiment (preset paper-fig3 with --set): steps: Input should be less
    # than or equal to 100000": a preset and a --set nobody gave
    with pytest.raises(ConfigError) as err:
        run_experiment("constraints", trials=1, steps=steps, workers=1, out=tmp_path / "e")
    assert str(err.value) == f"--steps {shown}: must be an integer in [1, 100000]"
    assert not (tmp_path / "e").exists()


def test_the_cli_blames_steps_past_the_bound_on_the_option(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "trackjam", "experiment", "table1", "--trials", "1", "--steps", "100001",
         "--out", str(tmp_path / "e")], capture_output=True, text=True, env=ENV, timeout=120)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.splitlines() == ["trackjam: error: --steps 100001: must be an integer in [1, 100000]"]
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("experiment, item, words", [
    # the area's message named only agents.initial: an experiment on Fig. 3's start keeps it
    # (experiments that draw their trials place their own, test_definitions)
    ("holding", "area.high=[1,1,1]", "agents.initial[0] [30.0, 30.0, 30.0] lies outside the `area` [0, 0, 0] to [1, 1, 1]"),
    # a --set that clashes with a configuration's own settings was blamed on the configuration
    ("constraints", "control.close_in=0.5", "control.close_in (0.5): control.constraints `false` plans"),
])
def test_a_set_that_makes_another_key_a_problem_is_blamed(tmp_path, experiment, item, words):
    with pytest.raises(ConfigError) as err:
        run_experiment(experiment, trials=1, steps=3, workers=1, out=tmp_path / "e", overrides=[item])
    assert str(err.value).startswith(f"--set {item}: {words}"), err.value
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("kind", ["fifo", "zero", "huge", "folder"])
def test_an_experiment_json_that_is_not_a_small_file_is_one_line_without_reading_it(tmp_path, kind):
    # a pipe waited forever for a writer; /dev/zero (a link to it) or a 16 GB file was read whole,
    # until the memory ran out. Checked in a process of limited memory and time, so that a
    # regression fails here instead of hanging or exhausting the machine
    import os
    import resource

    out = tmp_path / "e"
    out.mkdir()
    meta = out / "experiment.json"
    if kind == "fifo":
        os.mkfifo(meta)
    elif kind == "zero":
        meta.symlink_to("/dev/zero")
    elif kind == "huge":
        with open(meta, "wb") as f:
            f.truncate(2**34)  # 16 GB, sparse
    else:
        meta.mkdir()
    proc = subprocess.run([sys.executable, "-m", "trackjam", "experiment", "constraints", "--trials", "1", "--steps",
                           "2", "--workers", "1", "--out", str(out)], capture_output=True, text=True, env=ENV,
                          timeout=60, preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30)))
    what = "larger than 10 MB" if kind == "huge" else "not a regular file (a folder, a device or a pipe)"
    assert proc.returncode == 2 and proc.stderr == (
        f"trackjam: error: --out {out}: experiment.json is {what}; restore it, or remove the whole folder to start "
        "over, or choose another --out\n")
    assert sorted(p.name for p in out.iterdir()) == ["experiment.json"]


@pytest.mark.parametrize("option, value", [("trials", True), ("steps", True), ("workers", True)])
def test_a_bool_for_a_count_is_refused_through_the_api(tmp_path, option, value):
    # trials=True ran one trial and wrote "trials": true to experiment.json, which
    # summarise_folder then refused as mistyped; --seed already refused a bool
    with pytest.raises(ConfigError, match=rf"^--{option} must be a positive integer, got True$"):
        run_experiment("constraints", **{**SWEEP, option: value}, out=tmp_path / "e")
    assert not (tmp_path / "e").exists()


def test_a_trial_file_that_would_not_fit_in_memory_is_run_again_unread(done, tmp_path, monkeypatch):
    # a 15 kB hand-made file of one row holding 2e8 zeros took 30 s and 12 GB to read back;
    # a few more kB would have exhausted the machine. Here 1e6 zeros past a cap lowered to 1 MB.
    import numpy as np

    import trackjam.experiments.summary as summary

    out = tmp_path / "e"
    shutil.copytree(done, out)
    path = out / "trials" / trial_filename(1, 0)
    n = 1_000_000
    bomb = pa.ListArray.from_arrays(pa.array([0, n], pa.int32()), pa.array(np.zeros(n)))
    pq.write_table(pq.read_table(path).append_column("step.bomb", bomb), path, compression="zstd")
    assert path.stat().st_size < 100_000
    monkeypatch.setattr(summary, "TRIAL_MAX_VALUES", 100_000)
    read = []
    real = pq.read_table
    monkeypatch.setattr(summary.pq, "read_table", lambda p, *a, **k: (read.append(Path(getattr(p, "name", p)).name), real(p, *a, **k))[1])
    with pytest.raises(summary.DamagedTrial, match=rf"^{path.name}: .*larger than"):
        summary.read_trial(path)
    assert read == []
    result = run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert result.ran == 1 and any("damaged" in n and path.name in n for n in result.notes)
    assert (out / "summary.csv").read_bytes() == (done / "summary.csv").read_bytes()


def test_a_resume_holds_one_trials_per_step_series_at_a_time(tmp_path):
    # every trial read back kept its per-step series (20 of them in a real trial) until the
    # summary was written: a finished sweep of 200 trials of 100,000 steps held about 13 GB
    # to resume, which no check counted; the summary and the pairs read only the figures
    import tracemalloc

    sweep = {**SWEEP, "trials": 20, "steps": 20_000}  # 40 trials of 2 series of 20,000 steps
    first = run_experiment("constraints", workers=1, out=tmp_path / "e", **sweep)
    tracemalloc.start()
    try:
        again = run_experiment("constraints", workers=1, out=tmp_path / "e", **sweep)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert again.ran == 0 and again.summary == first.summary and again.paired == first.paired
    assert peak < 15e6, f"{peak / 1e6:.0f} MB"  # 40 trials' series as Python lists: about 55 MB


def test_an_experiment_json_that_differs_hugely_is_refused_in_a_short_line(done, tmp_path):
    # the line repeated both values whole: a hand-edited experiment.json of 5 MB made a 5.7 MB line,
    # one with 10,000 keys a part for each
    import json

    for edit in ({"overrides": ["x" * 5_000_000]}, {f"key{i}": i for i in range(10_000)}):
        out = tmp_path / f"e{len(edit)}"
        shutil.copytree(done, out)
        params = {**json.loads((out / "experiment.json").read_text()), **edit}
        (out / "experiment.json").write_text(json.dumps(params))
        with pytest.raises(ConfigError, match=rf"^--out {out}: holds a different experiment \(") as err:
            run_experiment("constraints", workers=1, out=out, **SWEEP)
        assert len(str(err.value)) < 600, len(str(err.value))


@pytest.mark.parametrize("option", ["trials", "steps", "workers"])
@pytest.mark.parametrize("sign", [1, -1])
def test_an_integer_of_thousands_of_digits_is_one_short_line(tmp_path, option, sign):
    # --workers 9...9 (4000 digits) was an OverflowError traceback; --trials the same a line of
    # 15,000 characters; a negative one repeated its 4000 digits
    options = {**SWEEP, "workers": 1, option: sign * (10**4000 - 1)}
    with pytest.raises(ConfigError, match=rf"^--{option} ") as err:
        run_experiment("constraints", **options, out=tmp_path / "e")
    assert len(str(err.value)) < 300, str(err.value)[:300]
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("options", [{"name": "a" * 100_000}, {"scheduler": "a" * 100_000},
                                     {"scheduler": "tcp://" + "a." * 50_000 + "b:8786"}])
def test_a_name_or_address_of_a_hundred_thousand_characters_is_one_short_line(tmp_path, options):
    # both were echoed whole: a line of 100 kB
    options = {"name": "constraints", **SWEEP, **options}
    with pytest.raises(ConfigError) as err:
        run_experiment(**options, out=tmp_path / "e")
    assert len(str(err.value)) < 300, str(err.value)[:300]
    assert not (tmp_path / "e").exists()


@pytest.mark.skipif(sys.platform == "win32", reason="the lock uses fcntl.flock")
def test_a_second_sweep_into_an_out_being_written_is_refused_and_changes_nothing(tmp_path):
    import fcntl

    out = tmp_path / "e"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    (out / "trials" / trial_filename(2, 1)).unlink()  # a trial left to run
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    with open(out / "experiment.json", "rb") as other:  # a sweep writing there holds this lock
        fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(ConfigError, match=r"another sweep is writing there .*choose another --out") as err:
            run_experiment("constraints", workers=1, out=out, **SWEEP)
        assert "\n" not in str(err.value)
        assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert run_experiment("constraints", workers=1, out=out, **SWEEP).ran == 1  # released: it resumes


@pytest.mark.skipif(sys.platform == "win32", reason="the lock uses fcntl.flock")
def test_the_lock_is_released_when_a_sweep_fails(tmp_path):
    out = tmp_path / "e"

    def failing(scenario):
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match="boom"):
        run_experiment("constraints", workers=1, out=out, **{**SWEEP, "trial": failing})
    import fcntl

    with open(out / "experiment.json", "rb") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)  # raises BlockingIOError if still held


def test_an_out_killed_between_its_experiment_json_and_its_trials_folder_resumes(tmp_path, monkeypatch):
    import trackjam.experiments.engine as engine

    out = tmp_path / "e"
    real_mkdir = Path.mkdir

    def killed(self, *args, **kwargs):  # the sweep dies as it creates trials/
        if self.name == "trials":
            raise KeyboardInterrupt
        return real_mkdir(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", killed)
    with pytest.raises(KeyboardInterrupt):
        engine.run_experiment("constraints", workers=1, out=out, **SWEEP)
    monkeypatch.setattr(Path, "mkdir", real_mkdir)
    assert (out / "experiment.json").is_file() and not (out / "trials").exists()
    assert engine.run_experiment("constraints", workers=1, out=out, **SWEEP).ran == 4


def _snapshot(folder: Path) -> dict:
    """Every entry under ``folder`` (links not followed): its kind, bytes and modification time."""
    return {p.relative_to(folder): (p.is_symlink(), p.read_bytes() if p.is_file() and not p.is_symlink() else None,
                                    p.lstat().st_mtime_ns) for p in folder.rglob("*")}


@pytest.mark.parametrize("target", ["other", "dangling"])
def test_a_trials_folder_that_is_a_link_is_refused_and_nothing_changes(done, tmp_path, target):
    # OUT/trials linked to another experiment's trials/: the run read that experiment's trials as
    # "run with other random streams" and replaced all 4 of them with its own
    other = tmp_path / "other"
    shutil.copytree(done, other)
    out = tmp_path / "e"
    run_experiment("constraints", workers=1, out=out, **{**SWEEP, "seed": 8})
    shutil.rmtree(out / "trials")
    (out / "trials").symlink_to(other / "trials" if target == "other" else tmp_path / "nowhere")
    before = _snapshot(out), _snapshot(other)
    with pytest.raises(ConfigError, match=rf"^--out {out}: trials is a symbolic link \(to .*\), and the trials would "
                                          r"be written and removed through it, in another folder; make it a plain "
                                          "folder or choose another --out$"):
        run_experiment("constraints", workers=1, out=out, **{**SWEEP, "seed": 8})
    assert (_snapshot(out), _snapshot(other)) == before
    assert not (tmp_path / "nowhere").exists()


def test_summarising_a_folder_whose_trials_are_a_link_is_refused(done, tmp_path):
    # reading the trials back removes stale temporary files: another sweep's, through the link
    from trackjam.experiments.engine import summarise_folder

    out = tmp_path / "e"
    shutil.copytree(done, out, ignore=shutil.ignore_patterns("trials"))
    (out / "trials").symlink_to(done / "trials")
    leftover = done / "trials" / f".{trial_filename(1, 0)}.abc.tmp.parquet"  # a sweep writing there
    leftover.write_bytes(b"half")
    try:
        with pytest.raises(ConfigError, match=rf"^{out}: trials is a symbolic link"):
            summarise_folder(out)
        assert leftover.read_bytes() == b"half"
    finally:
        leftover.unlink()


def test_the_cli_refuses_a_linked_trials_folder_in_one_line(done, tmp_path):
    import json

    from trackjam.experiments.definitions import get_experiment
    from trackjam.experiments.engine import _parameters, simulate_trial

    out = tmp_path / "e"
    out.mkdir()
    params = _parameters(get_experiment("constraints"), 1, 2, 0, [], simulate_trial)
    (out / "experiment.json").write_text(json.dumps(params))
    (out / "trials").symlink_to(done / "trials")
    before = _snapshot(done)
    proc = subprocess.run(
        [sys.executable, "-m", "trackjam", "experiment", "constraints", "--trials", "1", "--steps", "2",
         "--workers", "1", "--out", str(out)], capture_output=True, text=True, env=ENV, timeout=120)
    assert proc.returncode == 2 and proc.stderr.splitlines() == [
        f"trackjam: error: --out {out}: trials is a symbolic link (to {done / 'trials'}), and the trials would be "
        "written and removed through it, in another folder; make it a plain folder or choose another --out"]
    assert _snapshot(done) == before and sorted(p.name for p in out.iterdir()) == ["experiment.json", "trials"]


@pytest.mark.parametrize("name", ["summary.csv", "timing.csv", "paired.csv", "fig5.png"])
def test_a_result_at_a_linked_name_replaces_the_link_not_its_target(done, tmp_path, name):
    # results are renamed into place (trackjam.files.atomic_write): a link there is replaced by
    # the result, and the file it pointed to, another experiment's, stays as it was
    other = tmp_path / "other"
    shutil.copytree(done, other)
    out = tmp_path / "e"
    shutil.copytree(done, out)
    (other / name).write_bytes(b"the other experiment's")
    (out / name).unlink()
    (out / name).symlink_to(other / name)
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert (other / name).read_bytes() == b"the other experiment's"
    assert (out / name).is_file() and not (out / name).is_symlink()
    if name.endswith(".csv"):
        assert (out / name).read_bytes() == (done / name).read_bytes()


@pytest.mark.parametrize("value", [float("inf"), 1e308])
def test_a_trial_function_returning_a_huge_figure_is_refused_before_it_is_written(tmp_path, value):
    # written, it was read back as damaged and run again by every rerun
    from sweep_helpers import fake_trial

    def overflowing(scenario):
        return {**fake_trial(scenario), "ospa_mean": value}

    out = tmp_path / "e"
    with pytest.raises(ValueError, match=r"^the trial function returned ospa_mean past \+-1e\+100 "):
        run_experiment("constraints", workers=1, out=out, **{**SWEEP, "trial": overflowing})
    assert list((out / "trials").iterdir()) == []


def test_a_sweep_that_cannot_write_its_parameters_leaves_no_folder_it_made(tmp_path, monkeypatch):
    """On a full disk the sweep said so in one line but left OUT behind, made and empty (a run
    removes the folders it made); what was there before stays."""
    import errno

    from trackjam.experiments import engine

    def full(path, write):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(engine, "atomic_write", full)
    out = tmp_path / "new" / "deeper" / "sweep"
    with pytest.raises(ConfigError, match=r"cannot write there \(No space left on device\)"):
        engine.run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "kept").mkdir()
    (tmp_path / "kept" / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="cannot write there"):
        engine.run_experiment("constraints", workers=1, out=tmp_path / "kept" / "sweep", **SWEEP)
    assert [p.name for p in (tmp_path / "kept").iterdir()] == ["notes.txt"]
