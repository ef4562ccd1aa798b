"""Running an experiment's trials on a local process pool or a Dask cluster, resumably.

Both backends go through one ``concurrent.futures`` loop: a local ``ProcessPoolExecutor``
(spawn start method, one numba thread per worker), an in-process executor for one worker, or
``distributed.Client(address).get_executor()`` for an existing Dask cluster. The client writes
each finished trial at once as its own Parquet file in ``OUT/trials/``; a rerun into the same
OUT skips the trials already there. ``summary.csv`` depends only on the trial records, which
depend only on (experiment, trials, steps, seed, overrides): never on workers or backend.
"""

from __future__ import annotations

import json
import multiprocessing
import os
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import trackjam
from trackjam.config import Scenario
from trackjam.errors import ConfigError
from trackjam.experiments.definitions import (
    base_data,
    configuration_columns,
    draw_for,
    get_experiment,
    trial_scenario,
)
from trackjam.experiments.progress import make_reporter
from trackjam.experiments.summary import (
    METRICS,
    TIMING,
    finished_trials,
    read_trial,
    table_rows,
    trial_filename,
    write_table,
    write_trial,
)

TrialFunction = Callable[[Scenario], Mapping[str, Any]]
CONNECT_TIMEOUT_S = 5.0


def simulate_trial(scenario: Scenario) -> dict[str, Any]:
    """The real trial: one run of :func:`trackjam.simulate`, reduced to its summary figures,
    the per-agent jamming incidents and the per-step series."""
    from trackjam.simulation.loop import simulate

    result = simulate(scenario)
    record = {k: float(result.summary[k]) for k in (
        "jamming_incidents_per_agent", "target_received_w_mean", "agent_received_w_mean",
        "transmit_w_mean", "ospa_mean", "step_s_mean", "solve_s_mean",
    )}
    record["jamming_incidents"] = [int(v) for v in result.summary["jamming_incidents"]]
    record["steps"] = result.steps
    return record


def _one_numba_thread() -> None:
    """Trials run side by side: each worker gets one numba thread (before numba is imported
    when possible, else through ``numba.set_num_threads``)."""
    os.environ["NUMBA_NUM_THREADS"] = "1"
    import sys

    numba = sys.modules.get("numba")
    if numba is not None:
        numba.set_num_threads(1)


def run_trial(trial: TrialFunction, experiment: str, config: int, index: int, scenario: Scenario) -> dict:
    """Worker side of one trial: the record the client writes to ``OUT/trials/``."""
    _one_numba_thread()
    record = dict(trial(scenario))
    record.update(experiment=experiment, config=config, trial=index, seed=scenario.seed)
    return record


class SerialExecutor(Executor):
    """One worker: trials run in this process, one at a time, when their result is awaited."""

    def __init__(self) -> None:
        self._queue: list[tuple[Future, Callable, tuple]] = []

    def submit(self, fn, /, *args, **kwargs) -> Future:
        f: Future = Future()
        self._queue.append((f, fn, args))
        return f

    def run_next(self) -> None:
        f, fn, args = self._queue.pop(0)
        if f.set_running_or_notify_cancel():
            try:
                f.set_result(fn(*args))
            except BaseException as err:  # handed to the caller through the future
                f.set_exception(err)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        for f, _, _ in self._queue:
            f.cancel()
        self._queue.clear()


@contextmanager
def open_executor(workers: int | None, scheduler: str | None) -> Iterator[tuple[Executor, int]]:
    """The executor and how many trials to keep in flight."""
    if scheduler:
        yield from _dask_executor(scheduler)
        return
    n = workers or os.cpu_count() or 1
    if n == 1:
        ex: Executor = SerialExecutor()
    else:
        ex = ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("spawn"), initializer=_one_numba_thread)
    try:
        yield ex, 2 * n
    except BaseException:
        ex.shutdown(wait=False, cancel_futures=True)
        raise
    ex.shutdown(wait=True)


def _dask_executor(address: str) -> Iterator[tuple[Executor, int]]:
    try:
        from distributed import Client
    except ImportError:
        raise ConfigError("--scheduler needs dask.distributed: pip install 'trackjam[dask]'") from None
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as err:
        msg = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ConfigError(f"cannot reach the Dask scheduler at {address} within {CONNECT_TIMEOUT_S:g} s: {msg}") from None
    try:
        yield client.get_executor(), 1 << 30  # the scheduler balances the load: submit everything
    finally:
        client.close()


# ---------------------------------------------------------------------------------------------


@dataclass
class ExperimentResult:
    out: Path
    summary: list[dict[str, Any]]  # rows of summary.csv
    timing: list[dict[str, Any]]  # rows of timing.csv
    ran: int  # trials run now (the others were found in OUT)
    files: list[Path]


def _parameters(name: str, trials: int, steps: int, seed: int, overrides: list[str], trial: TrialFunction) -> dict:
    return {
        "experiment": name,
        "trials": trials,
        "steps": steps,
        "seed": seed,
        "overrides": list(overrides),
        "trial_function": f"{trial.__module__}.{trial.__qualname__}",
        "trackjam_version": trackjam.__version__,
    }


def _claim(out: Path, params: dict) -> None:
    """Create OUT, or check that it holds the same experiment with the same parameters."""
    meta = out / "experiment.json"
    if meta.exists():
        old = json.loads(meta.read_text())
        diff = [k for k in sorted(set(old) | set(params)) if old.get(k) != params.get(k)]
        if diff:
            parts = ", ".join(f"{k}: {old.get(k)!r} there, {params.get(k)!r} now" for k in diff)
            raise ConfigError(f"{out} holds a different experiment ({parts}); choose another --out")
    elif out.exists() and any(out.iterdir()):
        raise ConfigError(f"{out} is not empty and holds no experiment.json; choose another --out")
    else:
        (out / "trials").mkdir(parents=True, exist_ok=True)
        meta.write_text(json.dumps(params, indent=2) + "\n")
    (out / "trials").mkdir(exist_ok=True)


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
    trial: TrialFunction = simulate_trial,
) -> ExperimentResult:
    """Run (or resume) experiment ``name``: every configuration on the same ``trials`` trial
    draws of ``steps`` steps, then write summary.csv, timing.csv and the figure into ``out``
    (default ``runs/experiment-NAME``).

    ``progress``: "auto" (a rich bar on a terminal, else one line per trial), "bar", "lines",
    "none", or a callable ``(record, done, total)``. ``trial`` maps a scenario to a record
    (default: :func:`simulate_trial`); it must be importable by the workers.
    """
    experiment = get_experiment(name)
    if not isinstance(trials, int) or trials < 1:
        raise ConfigError(f"--trials must be a positive integer, got {trials!r}")
    if not isinstance(steps, int) or steps < 1:
        raise ConfigError(f"--steps must be a positive integer, got {steps!r}")
    if not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"--seed must be a non-negative integer, got {seed!r}")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"--workers must be a positive integer, got {workers!r}")
    if workers is not None and scheduler:
        raise ConfigError("--workers sets the local pool; with --scheduler the cluster's workers run the trials")
    overrides = list(overrides or [])
    out = Path(out) if out is not None else Path("runs") / f"experiment-{name}"

    # every scenario is built (and so validated) before anything runs or is written
    base = base_data(experiment, steps, overrides)
    draws = [draw_for(base, seed, k) for k in range(trials)]
    scenarios = {
        (c.index, d.index): trial_scenario(experiment, base, c, d, seed)
        for c in experiment.configurations
        for d in draws
    }
    configurations = [
        {"config": c.index, "label": c.label, **configuration_columns(scenarios[(c.index, 0)])}
        for c in experiment.configurations
    ]

    report = make_reporter(progress, experiment, configurations, total=len(scenarios))
    _claim(out, _parameters(name, trials, steps, seed, overrides, trial))
    folder = out / "trials"
    done = finished_trials(folder)
    todo = [key for key in scenarios if key not in done]
    records = [read_trial(folder / trial_filename(c, k)) for (c, k) in sorted(done & set(scenarios))]
    report.start(records)

    if todo:
        with open_executor(workers, scheduler) as (executor, window):
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
                        record = f.result()
                        write_trial(folder, record)
                        records.append(record)
                        report.trial(record)
            finally:
                for f in pending:
                    f.cancel()
                report.stop()
    else:
        report.stop()

    return _finish(out, experiment, configurations, records, ran=len(todo))


def _finish(out: Path, experiment, configurations: list[dict], records: list[Mapping], ran: int) -> ExperimentResult:
    from trackjam.experiments.figures import write_figure

    summary = table_rows(records, configurations, METRICS)
    timing = table_rows(records, configurations, TIMING)
    write_table(out / "summary.csv", summary)
    write_table(out / "timing.csv", timing)
    files = [out / "summary.csv", out / "timing.csv", write_figure(experiment, summary, out / experiment.figure)]
    return ExperimentResult(out, summary, timing, ran, files)


def summarise_folder(out: Path | str) -> ExperimentResult:
    """Rebuild summary.csv, timing.csv and the figure from OUT's trial files (no simulation)."""
    out = Path(out)
    meta = out / "experiment.json"
    if not meta.exists():
        raise ConfigError(f"{out}: no experiment.json here")
    params = json.loads(meta.read_text())
    experiment = get_experiment(params["experiment"])
    base = base_data(experiment, params["steps"], params["overrides"])
    d0 = draw_for(base, params["seed"], 0)
    configurations = [
        {"config": c.index, "label": c.label, **configuration_columns(trial_scenario(experiment, base, c, d0, params["seed"]))}
        for c in experiment.configurations
    ]
    records = [read_trial(p) for p in sorted((out / "trials").glob("c*.parquet"))]
    return _finish(out, experiment, configurations, records, ran=0)
