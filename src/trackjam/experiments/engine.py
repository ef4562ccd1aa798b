"""Running an experiment's trials, resumably, on this process, a local pool or a Dask cluster.

All backends go through one ``concurrent.futures`` loop (:mod:`trackjam.experiments.backends`).
The client writes each finished trial at once as its own Parquet file in ``OUT/trials/``; a
rerun into the same OUT reads back the trials that are there and intact, re-runs the damaged
ones and ignores files that are not its trials. ``summary.csv`` depends only on the trial
records, which depend only on (experiment, trials, steps, seed, overrides): never on workers or
backend. Nothing is written before the options, the scenarios, OUT and the scheduler (when
there is one) have all been checked.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import pickle
import pickletools
import sys
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

try:
    import fcntl
except ImportError:  # not on Windows: two sweeps into one OUT there are not told apart
    fcntl = None

import numpy as np

import trackjam
from trackjam.arguments import text_path
from trackjam.config import Scenario
from trackjam.config.loading import override_items
from trackjam.config.limits import MAX_STEPS, check_seed, check_trial_runs, check_workers, run_memory, shown_integer
from trackjam.errors import ConfigError, OutputError, printable, shortened
from trackjam.experiments.backends import SerialExecutor, one_numba_thread, open_executor, parse_scheduler_address
from trackjam.experiments.definitions import (
    EXPERIMENTS,
    SWARM,
    Experiment,
    base_data,
    base_scenario,
    configuration_columns,
    draw_for,
    get_experiment,
    owned_keys,
    swarm_scenario,
    trial_scenario,
)
from trackjam.experiments.swarm import swarm_trial
from trackjam.experiments.progress import make_reporter
from trackjam.simulation.build import check_swarm_options
from trackjam.experiments.summary import (
    TIMING,
    TRIAL_MAX_FIGURE,
    DamagedTrial,
    figure_problem,
    paired_rows,
    parse_trial_filename,
    read_trial,
    table_rows,
    trial_filename,
    write_table,
    write_trial,
)
from trackjam.files import (
    atomic_write,
    check_writable,
    existing_folder,
    is_temporary_of,
    kind_of,
    remove_leftover,
    remove_temporaries,
    taken_by,
)

TrialFunction = Callable[[Scenario], Mapping[str, Any]]


def simulate_trial(scenario: Scenario) -> dict[str, Any]:
    """The real trial: one run of :func:`trackjam.simulate`, reduced to its summary figures,
    the per-agent jamming incidents and the per-step series."""
    from trackjam.simulation.loop import simulate

    result = simulate(scenario)
    record = {k: float(result.summary[k]) for k in (
        "jamming_incidents_per_agent", "target_received_w_mean", "agent_received_w_mean",
        "transmit_w_mean", "ospa_mean", "step_s_mean", "solve_s_mean",
    )}
    for k in ("held_share", "false_track_share", "missed_share", "ceiling_share", "reacquired_after_last_spell"):
        value = result.summary[k]  # None where it does not apply (no detectable step, no spell)
        record[k] = math.nan if value is None else float(value)
    record["jamming_incidents"] = [int(v) for v in result.summary["jamming_incidents"]]
    record["steps"] = result.steps
    return record


def scenario_digest(scenario: Scenario) -> str:
    """A fingerprint of everything a trial's scenario sets (seed, steps, every setting, so every
    --set): a trial file of another run of the same experiment is told apart from this run's.
    Only what differs from the defaults counts, so an option a later trackjam adds (its default
    the earlier behaviour) does not make every earlier trial file look foreign."""
    text = json.dumps(scenario.model_dump(mode="json", exclude_defaults=True), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


_SIMULATING = (simulate_trial, swarm_trial)  # the trials that run our engines, warmed up first
_WARMED: set[tuple[str, int]] = set()  # (experiment, configuration) this process has warmed up


def run_trial(trial: TrialFunction, experiment: str, config: int, index: int, scenario: Scenario) -> dict:
    """Worker side of one trial: the record the client writes to ``OUT/trials/``.

    Before its first trial of a configuration, a process runs the scenario's warm-up twin
    (:func:`trackjam.simulation.warmup.warm_up`, as ``trackjam run`` does) when the trial is a
    simulation of ours, so that numba's compilation (or its loading from the cache) is not timed
    in ``step_s``: a first sweep's timing.csv read about ten times the steps' cost before. The
    twin shares no random stream with the trial, so the record is the same either way."""
    one_numba_thread()
    if trial in _SIMULATING and (experiment, config) not in _WARMED:
        from trackjam.simulation.warmup import warm_up

        warm_up(scenario)
        _WARMED.add((experiment, config))
    record = dict(trial(scenario))
    record.update(experiment=experiment, config=config, trial=index, seed=scenario.seed,
                  scenario=scenario_digest(scenario))
    return record


# ---------------------------------------------------------------------------------------------


@dataclass
class ExperimentResult:
    out: Path
    summary: list[dict[str, Any]]  # rows of summary.csv
    timing: list[dict[str, Any]]  # rows of timing.csv
    ran: int  # trials run now (the others were found in OUT)
    files: list[Path]
    notes: list[str] = field(default_factory=list)  # what the resume found damaged or foreign
    paired: list[dict[str, Any]] = field(default_factory=list)  # rows of paired.csv (none without pairs)


def _check_count(option: str, value: Any) -> None:
    """Refuse, in one line naming ``option``, a count that is not a positive integer (a bool is
    not one; an integer of many digits is shown by its size, :func:`shown_integer`)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        shown = shown_integer(value) if isinstance(value, int) else repr(value)
        raise ConfigError(f"{option} must be a positive integer, got {shown}")


def _parameters(experiment: Experiment, trials: int, steps: int, seed: int, overrides: list[str],
                trial: TrialFunction) -> dict:
    grid = {} if experiment.grid is None else {"grid": experiment.grid}
    return {
        "experiment": experiment.name,
        **grid,
        "trials": trials,
        "steps": steps,
        "seed": seed,
        "overrides": list(overrides),
        # the experiment's own settings on its preset: a folder run under other ones is not resumed
        "settings": dict(experiment.base_settings),
        "trial_function": f"{trial.__module__}.{trial.__qualname__}",
        "trackjam_version": trackjam.__version__,
    }


PARAMETERS_MAX_BYTES = 10_000_000  # an experiment.json is a few hundred bytes and its --set items


def read_parameters(meta: Path, where: str | None = None) -> dict:
    """The parameters in ``OUT/experiment.json``, or a one-line ConfigError if it is unreadable:
    not a regular file (a pipe waits for a writer forever, /dev/zero never ends), too large to
    be ours, or not an experiment's parameters. The line begins with ``where`` (``--out OUT``,
    the option it came from) when given, else with the file's path."""
    # removing experiment.json alone leaves a folder a sweep refuses ("holds no experiment.json")
    fix = "restore it, or remove the whole folder to start over, or choose another --out"
    head = f"{where}: {meta.name} is" if where is not None else f"{meta}:"
    if not meta.is_file():
        raise ConfigError(f"{head} not a regular file (a folder, a device or a pipe); {fix}")
    if meta.stat().st_size > PARAMETERS_MAX_BYTES:
        raise ConfigError(f"{head} larger than {PARAMETERS_MAX_BYTES // 1_000_000} MB; {fix}")
    try:
        params = json.loads(meta.read_text())
    except (OSError, ValueError, RecursionError) as err:  # UnicodeDecodeError, JSONDecodeError, an integer
        # past 4300 digits, [[[[... nested deeper than the parser recurses
        reason = "empty" if meta.is_file() and meta.stat().st_size == 0 else type(err).__name__
        raise ConfigError(f"{head} unreadable ({reason}); {fix}") from None
    if not isinstance(params, dict) or "experiment" not in params:
        raise ConfigError(f"{head} not an experiment's parameters; {fix}")
    return params


def _check_out(out: Path, params: dict, figure: str) -> None:
    """Refuse an OUT that is a file, unwritable, holds something else, or holds something other
    than a file where a result goes (summary.csv, timing.csv, paired.csv, ``figure``); writes nothing."""
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out}: is {kind_of(out)}, not a folder")
    meta = out / "experiment.json"
    if meta.exists() or meta.is_symlink():
        old = read_parameters(meta, f"--out {out}")
        diff = [k for k in sorted(set(old) | set(params)) if old.get(k) != params.get(k)]
        if diff:  # each value shortened: a hand-edited experiment.json may hold megabytes
            parts = _names([f"{shortened(k, 40)}: {shortened(repr(old.get(k)), 60)} there, "
                            f"{shortened(repr(params.get(k)), 60)} now" for k in diff], shown=len(params))
            raise ConfigError(f"--out {out}: holds a different experiment ({parts}); choose another --out")
        _check_trials_folder(out, f"--out {out}")
    elif out.is_dir() and any(out.iterdir()):
        raise ConfigError(f"--out {out}: is not empty and holds no experiment.json; choose another --out")
    check_writable(existing_folder(out, f"--out {out}"), f"--out {out}")
    for written in ("summary.csv", "timing.csv", "paired.csv", figure):
        if what := taken_by(out / written):
            raise ConfigError(f"--out {out}: {written} is {what}, not a file; move it away or choose another --out")


def _check_trials_folder(out: Path, where: str) -> None:
    """Refuse, in one line beginning with ``where``, an OUT/trials that is a file or a symbolic
    link. Trials are written, and stale temporary files removed, inside it: through a link (to
    another experiment's trials/, say) a run replaced that experiment's trial files. A result at
    a linked name in OUT (summary.csv, the figure) is not written through:
    :func:`trackjam.files.atomic_write` renames over the link and leaves its target alone."""
    trials = out / "trials"
    if trials.is_symlink():
        raise ConfigError(f"{where}: trials is a symbolic link (to {shortened(os.readlink(trials), 120)}), and "
                          "the trials would be written and removed through it, in another folder; "
                          "make it a plain folder or choose another --out")
    if trials.exists() and not trials.is_dir():
        raise ConfigError(f"{where}: trials is a file, not a folder")


def _check_trial_slots(folder: Path, scenarios: Mapping[tuple[int, int], Scenario], where: str) -> None:
    """Refuse, in one line beginning with ``where``, a trial of this run whose file name in
    ``folder`` is held by something other than a file (a folder, a pipe): the trial would be
    run and then fail to be written (``Is a directory``), after the trials before it."""
    if not folder.is_dir():
        return
    for p in folder.iterdir():
        if parse_trial_filename(p.name) in scenarios and (what := taken_by(p)):
            raise ConfigError(f"{where}: trials/{p.name} is {what}, not a file; move it away or choose another --out")


def _claim(out: Path, params: dict) -> None:
    """Write experiment.json (atomically) unless it is there, then create OUT/trials: in that
    order a sweep killed in between leaves an OUT that resumes (the other order left a
    ``trials/`` without experiment.json, which a rerun refuses as a folder holding something else)."""
    made = [p for p in (out, *out.parents) if not p.exists()][::-1]  # the folders this sweep creates, outermost first
    try:
        out.mkdir(parents=True, exist_ok=True)
        meta = out / "experiment.json"
        if not meta.exists():
            atomic_write(meta, lambda tmp: tmp.write_text(json.dumps(params, indent=2) + "\n"))
        (out / "trials").mkdir(exist_ok=True)
    except OSError as err:
        # a full disk left OUT made and empty (a run removes the folders it made): so does a sweep
        for p in reversed(made):
            try:
                p.rmdir()  # only if empty: what another process put there stays
            except OSError:
                break
        raise ConfigError(f"--out {out}: cannot write there ({err.strerror or err})") from None


@contextlib.contextmanager
def _locked(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on OUT/experiment.json while a sweep writes into OUT: a second sweep
    into the same OUT is refused in one line, where it would have deleted the first one's
    in-progress temporary files and run its trials twice. The lock goes with the process (even
    after a SIGKILL); the file is written once, so the lock holds the one inode every sweep opens."""
    if fcntl is None:
        yield
        return
    try:
        fh = open(out / "experiment.json", "rb")
    except OSError as err:
        raise ConfigError(f"--out {out}: cannot read experiment.json ({err.strerror or err})") from None
    with fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ConfigError(f"--out {out}: another sweep is writing there (its experiment.json is locked); "
                              "wait for it to finish, or choose another --out") from None
        except OSError:  # a file system without locks (some network mounts): go on unlocked
            pass
        yield


def record_keys(experiment: Experiment) -> tuple[str, ...]:
    """The figures every trial record of ``experiment`` must hold: its metrics and the timings."""
    return tuple(dict.fromkeys(k for _, k, _ in experiment.metrics + experiment.counts + TIMING))


def _read_back(folder: Path, experiment: Experiment, scenarios: Mapping[tuple[int, int], Scenario]) -> tuple[dict, list[str]]:
    """The intact trial records in ``folder`` by (config, trial) run on ``scenarios``, and one
    line for each kind of file passed over: damaged trials, trials of other seeds or settings
    (all re-run) and files that are not this experiment's trials (left alone). Stale temporary
    files of interrupted writes are removed."""
    name = experiment.name
    keys = record_keys(experiment)
    records: dict[tuple[int, int], dict] = {}
    damaged, foreign, stale, other = [], [], [], []
    for p in sorted(folder.iterdir()):
        if _leftover(p):
            remove_leftover(p)
            continue
        key = parse_trial_filename(p.name)
        if key is not None and key in scenarios and p.is_symlink() and not p.exists():
            damaged.append(p.name)  # a link to no file: the trial is run and its file put in the link's place
            continue
        if key is None or key not in scenarios or not p.is_file():
            foreign.append(p.name)
            continue
        try:
            record = read_trial(p, keys)
        except DamagedTrial:
            damaged.append(p.name)
            continue
        if (record["experiment"], record["config"], record["trial"]) != (name, *key):
            damaged.append(p.name)
            continue
        if record["seed"] != scenarios[key].seed:  # run with other random streams (an earlier trackjam's seeding)
            stale.append(p.name)
            continue
        # copied from a run with other --steps or --set; a file of a trackjam that wrote no
        # fingerprint (the committed sweeps in docs/experiments) is taken on its seed
        if record.get("scenario", None) not in (None, scenario_digest(scenarios[key])):
            other.append(p.name)
            continue
        records[key] = _figures(record)
    notes = []
    if damaged:
        notes.append(f"{len(damaged)} damaged trial file(s) in {folder} will be run again: {_names(damaged)}")
    if stale:
        notes.append(f"{len(stale)} trial file(s) in {folder} were run with other random streams (an earlier "
                     f"trackjam's seeds) and will be run again: {_names(stale)}")
    if other:
        notes.append(f"{len(other)} trial file(s) in {folder} were run with other settings than this run's (another "
                     f"--steps or --set) and will be run again: {_names(other)}")
    if foreign:
        notes.append(f"ignoring {len(foreign)} file(s) in {folder} that are not trials of this experiment: {_names(foreign)}")
    return records, notes


def _figures(record: Mapping[str, Any]) -> dict:
    """A record without its per-step and per-agent lists: what the summary, the pairs and the
    progress read, so that a sweep holds one trial's series at a time, not every trial's."""
    return {k: v for k, v in record.items() if not isinstance(v, (list, tuple, dict)) and getattr(v, "ndim", 0) == 0}


def _leftover(p: Path) -> bool:
    """``p`` is what an interrupted write of a trial file left (a user's dot file is not)."""
    key = parse_trial_filename(p.name[1:].partition(".parquet.")[0] + ".parquet")
    return key is not None and p.is_file() and is_temporary_of(p, trial_filename(*key))


def _names(names: list[str], shown: int = 3) -> str:
    return ", ".join(names[:shown]) + (f" and {len(names) - shown} more" if len(names) > shown else "")


def _plan(experiment: Experiment, trials: int, steps: int, seed: int, overrides: list[str]):
    """Every (config, trial) scenario, built and so validated, and the configuration columns."""
    base = base_data(experiment, steps, overrides)
    # a bad --set is named here, before any trial
    space = base_scenario(base, experiment.preset, overrides, owned_keys(experiment))
    if experiment.trials == SWARM:
        # trial-major: a sweep stopped early leaves every cell with the same trials
        scenarios = {(c.index, k): swarm_scenario(experiment, space, base, c, k, seed)
                     for k in range(trials) for c in experiment.configurations}
        for c in experiment.configurations:  # an option the swarm engine does not read: refused here, not by a worker
            # every cell that lists its targets runs on the swarm engine, K = 1 too (swarm_trial): a
            # grid of K = 1 alone (--grid 1x3) had started the sweep, its first trial then refused
            if scenarios[(c.index, 0)].targets is not None:
                check_swarm_options(scenarios[(c.index, 0)], overrides)
    else:
        draws = [draw_for(base, seed, k, space) for k in range(trials)]
        scenarios = {
            (c.index, d.index): trial_scenario(experiment, base, c, d, seed, overrides)
            for c in experiment.configurations
            for d in draws
        }
    configurations = [
        {"config": c.index, "label": c.label, **configuration_columns(scenarios[(c.index, 0)]), **c.columns}
        for c in experiment.configurations
    ]
    return scenarios, configurations


def _importing_in_a_worker() -> bool:
    """Whether this process is a spawned worker still importing the parent's script (the test
    multiprocessing itself makes before refusing to start a process then)."""
    import multiprocessing

    return bool(getattr(multiprocessing.current_process(), "_inheriting", False))


def run_experiment(
    name: str,
    trials: int = 20,
    steps: int = 30,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    out: Path | str | None = None,
    overrides: list[str] | None = None,
    progress: str | Callable[[dict, int, int], None] = "auto",
    trial: TrialFunction | None = None,
    grid: str | None = None,
) -> ExperimentResult:
    """Run (or resume) experiment ``name``: every configuration on the same ``trials`` trial
    draws of ``steps`` steps, then write summary.csv, timing.csv and the figure into ``out``
    (default ``runs/experiment-NAME``).

    ``progress``: "auto" (a rich bar on a terminal, else one line per trial), "bar", "lines",
    "none", or a callable ``(record, done, total)``. ``trial`` maps a scenario to a record
    (default: the experiment's, else :func:`simulate_trial`); it must be importable by the
    workers. ``grid``: the swarm experiment's cells, TARGETSxAGENTS (default 1-4x3-6).
    """
    if _importing_in_a_worker():
        # a script without a main guard, imported again by each spawned worker: every worker had
        # started a sweep of its own ("another sweep is writing there"), the pool then "killed
        # from outside"
        raise RuntimeError("run_experiment: called while a worker process imports your script (the workers are "
                           "spawned, and each imports it): put the call under `if __name__ == \"__main__\":`")
    if not isinstance(name, str):  # None was a TypeError from deep in the message's own code
        raise TypeError(f"name: expected an experiment's name ({', '.join(EXPERIMENTS)}), got {type(name).__name__}")
    if trial is not None and not callable(trial):  # 5 was "'int' object has no attribute '__module__'"
        raise TypeError(f"trial: expected a function of a scenario that returns a record, got {type(trial).__name__}")
    if out is not None:
        text_path("out", out, "a folder's path")
    # 5 was "object of type 'int' has no len()" (scheduler) or an AttributeError (grid)
    for option, value, what in (("grid", grid, "TARGETSxAGENTS as text, e.g. '1-4x3-6'"),
                                ("scheduler", scheduler, "an address as text, [SCHEME://]HOST:PORT")):
        if value is not None and not isinstance(value, str):
            raise TypeError(f"{option}: expected {what}, got {type(value).__name__} {shortened(repr(value), 40)}")
    # a lone text was read a character at a time ("--set 's': expected key=value"), [5] was an
    # AttributeError: the list load_scenario takes, refused as it refuses it
    overrides = override_items(overrides)
    experiment = get_experiment(name, grid)
    trial = trial or experiment.trial or simulate_trial
    # numpy's integers are integers (a --seed np.int64(1) was "must be an integer"); JSON takes ints
    trials, steps, seed = (int(v) if isinstance(v, np.integer) else v for v in (trials, steps, seed))
    _check_arguments(trials, steps, seed, workers, scheduler)
    _check_sendable(trial, workers, scheduler)
    out = Path(out) if out is not None else Path("runs") / f"experiment-{name}"
    scenarios, configurations = _planned(experiment, trials, steps, seed, overrides, workers, scheduler)
    report = make_reporter(progress, experiment, configurations, total=len(scenarios))
    params = _parameters(experiment, trials, steps, seed, overrides, trial)
    _check_out(out, params, experiment.figure)
    _check_trial_slots(out / "trials", scenarios, f"--out {out}")

    with contextlib.ExitStack() as stack:  # the scheduler reached, then experiment.json, trials/ and the lock
        executor, window = stack.enter_context(open_executor(workers, scheduler))
        _claim(out, params)
        stack.enter_context(_locked(out))
        # what killed writes of OUT's summary or figure left (.fig4.png.m4kupqju.tmp.png)
        remove_temporaries(out, (*RESULT_FILES, experiment.figure))
        folder = out / "trials"
        records, todo, notes = _resume(folder, experiment, scenarios, report)
        _run_trials(executor, window, trial, name, experiment, scenarios, todo, folder, records, report)
        # still under the lock: a sweep starting now removes no temporary file of these writes
        return _finish(out, experiment, configurations, records, ran=len(todo), notes=notes,
                       ospa_cutoff=_ospa_cutoff(scenarios))


RESULT_FILES = ("experiment.json", "summary.csv", "timing.csv", "paired.csv")


def _check_arguments(trials: int, steps: int, seed: int, workers: int | None, scheduler: str | None) -> None:
    """Refuse, in one line naming the option, a --trials, --steps, --seed, --workers or
    --scheduler a sweep cannot take (--workers with --scheduler too), before anything is built."""
    _check_count("--trials", trials)
    _check_count("--steps", steps)
    if steps > MAX_STEPS:  # else blamed on the preset, "with --set" when none was given
        raise ConfigError(f"--steps {shown_integer(steps)}: must be an integer in [1, {MAX_STEPS}]")
    check_seed(seed)  # the range `run --seed` takes (SeedSequence would take any size)
    if workers is not None:
        _check_count("--workers", workers)
    if workers is not None and scheduler:
        raise ConfigError("--workers sets the local pool; with --scheduler the cluster's workers run the trials")
    if scheduler is not None:  # an empty one ran the trials locally, without a word
        parse_scheduler_address(scheduler)


def _check_sendable(trial: TrialFunction, workers: int | None, scheduler: str | None) -> None:
    """Refuse, in one line naming it, a trial function the local pool's workers cannot be sent (a
    lambda, a function defined inside another), which pickle sends by module and name: it was a
    PicklingError traceback at the first trial, after experiment.json and trials/ were written.
    This process's own trials (one local worker) take any function, and Dask sends its own way."""
    if scheduler or (workers or os.cpu_count() or 1) == 1:
        return
    what = f"{getattr(trial, '__name__', type(trial).__name__)} of module {getattr(trial, '__module__', '?')}"
    try:
        data = pickle.dumps(trial)
    except Exception:  # PicklingError, AttributeError ("Can't pickle local object"), TypeError
        raise TypeError(f"trial: {shortened(what, 80)} cannot be sent to the workers, which import it by its module "
                        "and name: define it at the top level of a module (or run with workers=1)") from None
    # a function of an interactive session (python -c, the REPL, a notebook) pickles as __main__.NAME,
    # but a spawned worker has no __main__ to import it from: each worker failed with "Can't get
    # attribute", and the pool's "ended abruptly (... perhaps for lack of memory)" came after
    # experiment.json and trials/ were written
    if not getattr(sys.modules.get("__main__"), "__file__", None) and _names_main(data):
        raise TypeError(f"trial: {shortened(what, 80)} cannot be sent to the workers, which import it by its module "
                        "and name: this session's __main__ has no file they can import; define it in a module of "
                        "its own (or run with workers=1)")


def _names_main(data: bytes) -> bool:
    """The pickle ``data`` refers to a name of the module ``__main__``."""
    try:
        return any(arg == "__main__" or (isinstance(arg, str) and arg.startswith("__main__ "))
                   for _, arg, _ in pickletools.genops(data))
    except Exception:  # pragma: no cover - pickle.dumps wrote it
        return False


def _planned(experiment: Experiment, trials: int, steps: int, seed: int, overrides: list[str],
             workers: int | None, scheduler: str | None):
    """:func:`_plan`, once the sweep is known to be small enough to build up front, then the local
    pool's workers checked against the memory its trials need (a cluster's are its own)."""
    check_trial_runs(trials, len(experiment.configurations))
    scenarios, configurations = _plan(experiment, trials, steps, seed, overrides)
    if scheduler is None:
        check_workers(workers or os.cpu_count() or 1, max(run_memory(s) for s in scenarios.values()))
    return scenarios, configurations


def _resume(folder: Path, experiment: Experiment, scenarios: Mapping[tuple[int, int], Scenario],
            report) -> tuple[list[dict], list[tuple[int, int]], list[str]]:
    """The trial records already in ``folder`` (by (config, trial)), the keys of the trials left
    to run, in ``scenarios``' order, and the notes on what the read-back passed over, each said
    through ``report``."""
    found, notes = _read_back(folder, experiment, scenarios)
    for line in notes:
        report.note(line)
    records = [found[key] for key in sorted(found)]
    todo = [key for key in scenarios if key not in found]
    return records, todo, notes


def _run_trials(executor: Executor, window: int, trial: TrialFunction, name: str, experiment: Experiment,
                scenarios: Mapping[tuple[int, int], Scenario], todo: list[tuple[int, int]], folder: Path,
                records: list[dict], report) -> None:
    """Run the ``todo`` trials through ``executor``, at most ``window`` in flight, each written to
    ``folder`` and added to ``records`` as it finishes (:func:`_keep`). The progress starts from
    the ``records`` found; on the way out (an error, Ctrl-C) the trials not started are cancelled
    and the progress stopped."""
    report.start(records)
    if todo and trial in _SIMULATING:
        report.note("each worker compiles the kernels, or loads them from numba's cache, before its first "
                    "trial of a configuration (untimed; the first run on a machine compiles for up to a minute)")
    pending: set[Future] = set()
    queue = iter(todo)
    try:
        while True:
            while len(pending) < window and (key := next(queue, None)) is not None:
                pending.add(executor.submit(run_trial, trial, name, key[0], key[1], scenarios[key]))
            if not pending:
                break
            if isinstance(executor, SerialExecutor):
                executor.run_next()
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in finished:
                _keep(f.result(), folder, name, experiment, records, report)
    finally:
        for f in pending:
            f.cancel()
        report.stop()


def _keep(record: dict, folder: Path, name: str, experiment: Experiment, records: list[dict], report) -> None:
    """Check a finished trial's ``record`` (:func:`_check_record`), write it to ``folder``, then add
    its figures to ``records`` and the progress."""
    _check_record(record, name, experiment)
    try:
        write_trial(folder, record)
    except OSError as err:
        raise OutputError(
            f"{folder}: trial {record['trial']} of configuration {record['config']} cannot be written "
            f"({err.strerror or err}); the {len(records)} trials written before it are intact"
        ) from None
    figures = _figures(record)
    records.append(figures)
    report.trial(figures)


def _check_record(record: Mapping[str, Any], name: str, experiment: Experiment) -> None:
    """Refuse, with a ValueError naming them, a record that lacks figures the experiment
    summarises or holds one past +-TRIAL_MAX_FIGURE (inf: a trial function's mistake), before
    the record is written: read back, such a file is damaged and would be run again each time."""
    missing = [k for k in record_keys(experiment) if k not in record]
    if missing:
        raise ValueError(f"the trial function returned no {', '.join(missing)} (experiment {name} needs them for "
                         "summary.csv or timing.csv)")
    huge = [k for k in record_keys(experiment) if isinstance(record[k], (int, float)) and abs(record[k]) > TRIAL_MAX_FIGURE]
    if huge:
        raise ValueError(f"the trial function returned {', '.join(huge)} past +-{TRIAL_MAX_FIGURE:g} "
                         f"(experiment {name} cannot summarise it)")
    wrong = [p for k in record_keys(experiment) if isinstance(record[k], (int, float))
             and (p := figure_problem(k, float(record[k])))]
    if wrong:  # read back, the file would be damaged and run again each time
        raise ValueError(f"the trial function returned {wrong[0]} (experiment {name} cannot summarise it)")


def _ospa_cutoff(scenarios: Mapping) -> float:
    """The largest OSPA cut-off c of the sweep's scenarios: no trial's OSPA exceeds it, so the
    figure's OSPA intervals stop there."""
    return max((s.metrics.ospa_cutoff for s in scenarios.values()), default=math.inf)


def _finish(out: Path, experiment, configurations: list[dict], records: list[Mapping], ran: int,
            notes: list[str], ospa_cutoff: float = math.inf) -> ExperimentResult:
    """Write summary.csv, timing.csv, paired.csv (where there are pairs) and the figure from
    ``records``, each atomically; one that cannot be written is one line (an OutputError)."""
    from trackjam.experiments.figures import write_figure

    summary = table_rows(records, configurations, experiment.metrics, experiment.counts)
    timing = table_rows(records, configurations, TIMING)
    files: list[Path] = []

    def put(name: str, write: Callable[[Path], object]) -> None:
        try:
            write(out / name)
        except OSError as err:
            raise OutputError(
                f"{out / name}: cannot be written ({err.strerror or err}); the trials in {out / 'trials'} are intact: "
                "rerun the same command once it can be written"
            ) from None
        files.append(out / name)

    put("summary.csv", lambda path: write_table(path, summary))
    put("timing.csv", lambda path: write_table(path, timing))
    paired = paired_rows(records, experiment.pairs, experiment.metrics, experiment.counts)  # none without pairs
    if paired:
        put("paired.csv", lambda path: write_table(path, paired))
    put(experiment.figure, lambda path: atomic_write(path, lambda tmp: write_figure(experiment, summary, tmp, ospa_cutoff)))
    return ExperimentResult(out, summary, timing, ran, files, notes, paired)


def summarise_folder(out: Path | str) -> ExperimentResult:
    """Rebuild summary.csv, timing.csv and the figure from OUT's intact trial files (no simulation)."""
    out = Path(out)
    meta = out / "experiment.json"
    if not meta.exists():
        raise ConfigError(f"{printable(str(out))}: no experiment.json here")
    params = read_parameters(meta)
    kinds = {"experiment": str, "trials": int, "steps": int, "seed": int, "overrides": list, "grid": (str, type(None))}
    wrong = [k for k, kind in kinds.items() if not isinstance(params.get(k), kind) or isinstance(params.get(k), bool)]
    if wrong:
        raise ConfigError(f"{meta}: {', '.join(wrong)} missing or mistyped; not an experiment's parameters")
    if not all(isinstance(o, str) for o in params["overrides"]):
        raise ConfigError(f"{meta}: overrides must be --set items (texts); not an experiment's parameters")
    try:  # the bounds run_experiment holds them to: trials 10^9 built scenarios until the memory ran out
        _check_arguments(params["trials"], params["steps"], params["seed"], None, None)
        experiment = get_experiment(params["experiment"], params.get("grid"))
        check_trial_runs(params["trials"], len(experiment.configurations))
    except ConfigError as err:
        raise ConfigError(f"{meta}: {err}; not the parameters of a sweep trackjam runs") from None
    _check_trials_folder(out, str(out))  # reading it back removes stale temporary files there
    if not (out / "trials").is_dir():
        raise ConfigError(f"{out}: no trials/ folder here, nothing to summarise")
    scenarios, configurations = _plan(experiment, params["trials"], params["steps"], params["seed"], params["overrides"])
    found, notes = _read_back(out / "trials", experiment, scenarios)
    if not found:  # tables of NaN, written without a word
        raise ConfigError(f"{out / 'trials'}: no intact trial of this experiment, nothing to summarise"
                          + (f" ({'; '.join(notes)})" if notes else ""))
    return _finish(out, experiment, configurations, [found[k] for k in sorted(found)], ran=0, notes=notes,
                   ospa_cutoff=_ospa_cutoff(scenarios))
