"""The sweep engine: results depend on the trials only, never on workers, backend or
interruptions; a finished trial is never lost; bad input fails at once with one line.

The trials here are ``sweep_helpers.fake_trial``, a cheap deterministic stand-in for the
simulation, so the engine is tested on its own (test_real_trials.py runs the real loop).
"""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest

from trackjam.experiments.definitions import get_experiment
from sweep_helpers import ENV, SWEEP, failing_trial, free_port, kill, start, wait_for_files

from trackjam.errors import ConfigError
from trackjam.experiments.engine import run_experiment, summarise_folder
from trackjam.experiments.summary import read_table


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> bytes:
    out = tmp_path_factory.mktemp("serial")
    r = run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert r.ran == 4 and len(list((out / "trials").glob("*.parquet"))) == 4
    return (out / "summary.csv").read_bytes()


@pytest.fixture(scope="module")
def cluster():
    """A real Dask cluster on 127.0.0.1: a scheduler and two single-thread workers, whose BLAS
    runs single-threaded as under Dask's nanny (which sets OMP_NUM_THREADS=1)."""
    address = f"tcp://127.0.0.1:{free_port()}"
    procs = [start(["-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
                     address.rsplit(":", 1)[1], "--no-dashboard"])]
    for _ in range(2):
        procs.append(start(["-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                             "--no-dashboard", "--no-nanny"],
                           env=ENV | {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}))
    from distributed import Client

    client = Client(address, timeout=30)
    client.wait_for_workers(2, timeout=60)
    client.close()
    yield address, procs
    for p in procs:
        kill(p)


def test_the_summary_is_the_same_with_one_and_two_local_workers(reference, tmp_path):
    r = run_experiment("constraints", workers=2, out=tmp_path, **SWEEP)
    assert (tmp_path / "summary.csv").read_bytes() == reference
    rows = read_table(tmp_path / "summary.csv")
    assert [row["constraints"] for row in rows] == ["true", "false"]
    assert [row["trials"] for row in rows] == ["2", "2"]
    assert "step_s_mean" not in rows[0] and "step_s_mean" in read_table(tmp_path / "timing.csv")[0]
    assert (tmp_path / "fig5.png").stat().st_size > 0
    assert r.summary[0]["incidents_mean"] == pytest.approx(float(rows[0]["incidents_mean"]), rel=1e-5)


# the real simulation, as small as it gets: 3 steps, few particles, few GRASP samples
TINY = ["filter.particles=200", "filter.birth_particles=50", "control.grasp.samples=20", "control.grasp.iterations=2"]


def _without_times(record: dict) -> str:
    """The record as exact text (floats to the last digit, NaN equal to NaN), without the wall times."""
    import json
    import re

    return json.dumps({k: v for k, v in record.items() if not re.search(r"(step|solve)_s\b|_s_mean$", k)},
                      sort_keys=True, default=str)


def test_real_trials_give_the_same_summary_with_one_or_two_workers_and_on_dask(cluster, tmp_path):
    from trackjam.experiments.summary import read_trial

    address, _ = cluster
    sweep = dict(trials=2, steps=8, seed=3, progress="none", overrides=TINY)
    runs = {
        "serial": run_experiment("constraints", workers=1, out=tmp_path / "serial", **sweep),
        "pool": run_experiment("constraints", workers=2, out=tmp_path / "pool", **sweep),
        "dask": run_experiment("constraints", scheduler=address, out=tmp_path / "dask", **sweep),
    }
    ref = (tmp_path / "serial" / "summary.csv").read_bytes()
    for name in ("pool", "dask"):
        assert (tmp_path / name / "summary.csv").read_bytes() == ref, name
    # and every trial to the bit: Dask's workers run with OMP_NUM_THREADS=1, under which
    # OpenBLAS had given covariance intersection's weights other last digits
    trials = sorted(p.name for p in (tmp_path / "serial" / "trials").glob("*.parquet"))
    assert len(trials) == 4
    for name in ("pool", "dask"):
        for trial in trials:
            assert _without_times(read_trial(tmp_path / name / "trials" / trial)) == \
                _without_times(read_trial(tmp_path / "serial" / "trials" / trial)), (name, trial)
    rows = runs["serial"].summary
    assert [r["trials"] for r in rows] == [2, 2]
    for r in rows:  # the metrics are those of Fig. 5, in their ranges
        assert 0 <= r["incidents_mean"] <= 8 and 0 <= r["ospa_mean"] <= 10  # at most one a step per agent
        assert 0 <= r["transmit_w_mean"] <= 10**0.05 + 1e-12
    # a trial file holds the run's per-step series
    record = read_trial(tmp_path / "serial" / "trials" / "c01-t0000.parquet")
    assert record["step.t"] == [float(t) for t in range(1, 9)] and len(record["jamming_incidents"]) == 3  # one per agent


def test_the_summary_is_the_same_on_a_dask_cluster_and_survives_a_worker_killed_mid_sweep(
    reference, cluster, tmp_path, monkeypatch
):
    address, procs = cluster
    run_experiment("constraints", scheduler=address, out=tmp_path / "dask", **SWEEP)
    assert (tmp_path / "dask" / "summary.csv").read_bytes() == reference

    # slow trials; once the first is written, one worker dies with whatever it was running
    monkeypatch.setenv("TRACKJAM_FAKE_SLEEP", "0.5")
    out = tmp_path / "killed"
    killer = threading.Thread(target=lambda: (wait_for_files(out / "trials", 1), kill(procs[1])))
    killer.start()
    r = run_experiment("constraints", scheduler=address, out=out, **{**SWEEP, "trials": 4})
    killer.join()
    assert procs[1].poll() is not None  # the worker is dead
    assert r.ran == 8 and len(list((out / "trials").glob("*.parquet"))) == 8
    uninterrupted = run_experiment("constraints", workers=1, out=tmp_path / "ref4", **{**SWEEP, "trials": 4})
    assert (out / "summary.csv").read_bytes() == (tmp_path / "ref4" / "summary.csv").read_bytes()
    assert r.summary == uninterrupted.summary


def test_a_sweep_killed_mid_run_resumes_to_the_same_summary(reference, tmp_path):
    out = tmp_path / "sweep"
    env = {**ENV, "TRACKJAM_FAKE_SLEEP": "0.4"}
    proc = start(["-m", "sweep_helpers", "constraints", str(out), "2", "4"], env=env)
    try:
        wait_for_files(out / "trials", 2, proc)
    finally:
        kill(proc)  # SIGKILL to the sweep and its pool workers
    kept = len(list((out / "trials").glob("c*.parquet")))
    assert 2 <= kept < 8
    r = run_experiment("constraints", workers=2, out=out, **{**SWEEP, "trials": 4})
    assert r.ran == 8 - kept
    fresh = run_experiment("constraints", workers=1, out=tmp_path / "fresh", **{**SWEEP, "trials": 4})
    assert (out / "summary.csv").read_bytes() == (tmp_path / "fresh" / "summary.csv").read_bytes()
    assert r.summary == fresh.summary
    assert not list((out / "trials").glob(".*"))  # no temporary file is left behind


def test_a_rerun_skips_finished_trials_and_rebuilding_gives_the_same_summary(reference, tmp_path):
    run_experiment("constraints", workers=1, out=tmp_path, **SWEEP)
    again = run_experiment("constraints", workers=1, out=tmp_path, **SWEEP)
    assert again.ran == 0
    assert (tmp_path / "summary.csv").read_bytes() == reference
    (tmp_path / "summary.csv").unlink()
    summarise_folder(tmp_path)
    assert (tmp_path / "summary.csv").read_bytes() == reference
    params = json.loads((tmp_path / "experiment.json").read_text())
    assert params["experiment"] == "constraints" and params["trials"] == 2 and params["seed"] == 7


def test_a_failing_trial_stops_the_sweep_and_keeps_the_trials_already_written(tmp_path):
    with pytest.raises(RuntimeError, match="constraints-c1-t1 failed"):
        run_experiment("constraints", workers=1, out=tmp_path, **{**SWEEP, "trial": failing_trial})
    assert [p.name for p in (tmp_path / "trials").iterdir()] == ["c01-t0000.parquet"]


def test_resuming_into_a_folder_of_another_experiment_is_refused(tmp_path):
    run_experiment("constraints", workers=1, out=tmp_path, **SWEEP)
    with pytest.raises(ConfigError, match="different experiment.*seed: 7 there, 8 now") as err:
        run_experiment("constraints", workers=1, out=tmp_path, **{**SWEEP, "seed": 8})
    assert str(err.value).startswith(f"--out {tmp_path}: holds a different experiment (")  # the option first
    with pytest.raises(ConfigError, match="different experiment"):
        run_experiment("solvers", workers=1, out=tmp_path, **SWEEP)
    # the same experiment, whose own settings have changed since the folder's trials were run
    meta = tmp_path / "experiment.json"
    params = json.loads(meta.read_text())
    assert params["settings"] == get_experiment("constraints").base_settings
    meta.write_text(json.dumps({**params, "settings": {"control.solver": "grasp"}}))
    with pytest.raises(ConfigError, match=r"different experiment \(settings: \{'control.solver': 'grasp'\} there, \{\} now\)"):
        run_experiment("constraints", workers=1, out=tmp_path, **SWEEP)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not empty") as err:
        run_experiment("constraints", workers=1, out=tmp_path / "other", **SWEEP)
    assert str(err.value) == (f"--out {tmp_path / 'other'}: is not empty and holds no experiment.json; "
                              "choose another --out")


def test_plain_progress_prints_one_line_per_trial_with_running_means(tmp_path, capsys):
    run_experiment("constraints", workers=1, out=tmp_path, **{**SWEEP, "progress": "lines"})
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4
    assert lines[0].startswith("[1/4] config 1 (constraints on) trial 0: incidents")
    assert "running means over all configurations:" in lines[-1]


def test_plain_progress_says_a_slow_sweep_is_still_at_work(tmp_path, capsys, monkeypatch):
    """A trial of 100,000 steps runs for many minutes; the plain lines say every HEARTBEAT_S
    that the sweep is at work (shortened here), and the heartbeat stops with the sweep."""
    from trackjam.experiments import progress

    monkeypatch.setattr(progress, "HEARTBEAT_S", 0.2)
    monkeypatch.setenv("TRACKJAM_FAKE_SLEEP", "1.0")
    run_experiment("constraints", workers=1, out=tmp_path, **{**SWEEP, "trials": 1, "progress": "lines"})
    lines = capsys.readouterr().out.splitlines()
    beats = [k for k, line in enumerate(lines) if line.startswith("constraints: still at work, ")]
    assert beats and lines[beats[0]].startswith("constraints: still at work, 0 of 2 trials done after ")
    assert lines[-1].startswith("[2/2] ")  # the trials' own lines, in order
    assert not [t for t in threading.enumerate() if t.name == "trackjam-progress"]


@pytest.mark.parametrize(("seconds", "shown"), [(0, "0 s"), (42.9, "42 s"), (300, "5 min 00 s"),
                                                 (3725, "1 h 02 min")])
def test_elapsed_times_read_as_people_write_them(seconds, shown):
    from trackjam.experiments.progress import _elapsed

    assert _elapsed(seconds) == shown


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"name": "table9"}, "unknown experiment 'table9'"),
        ({"trials": 0}, "--trials must be a positive integer"),
        ({"steps": 0}, "--steps must be a positive integer"),
        ({"workers": 0}, "--workers must be a positive integer"),
        ({"progress": "loud"}, "progress must be one of"),
        ({"overrides": ["antenna.opening_angle_deg=200"]}, "opening angle must be in"),
    ],
)
def test_bad_input_is_a_one_line_error_and_writes_nothing(tmp_path, kwargs, words):
    args = {"name": "constraints", "workers": 1, "out": tmp_path / "out", **SWEEP, **kwargs}
    with pytest.raises(ConfigError, match=words) as err:
        run_experiment(**args)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "out").exists()


def test_an_unreachable_scheduler_fails_with_a_clear_error(tmp_path):
    address = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
    with pytest.raises(ConfigError, match=f"cannot reach the Dask scheduler at {address}") as err:
        run_experiment("constraints", scheduler=address, out=tmp_path, **SWEEP)
    assert "\n" not in str(err.value)
    assert not any(tmp_path.iterdir())  # checked before anything is written


def test_a_worker_warms_up_once_per_configuration_before_timing_and_the_record_is_unchanged(monkeypatch):
    """run_trial runs the scenario's warm-up twin before a process's first trial of each
    configuration of our own trials (so compilation is not timed in step_s), once only, never
    for a trial function of the caller's, and the record is the one without the warm-up."""
    import trackjam.experiments.engine as engine
    import trackjam.simulation.warmup as warmup
    from trackjam.config.loading import load_scenario

    s = load_scenario("paper-fig3", ["steps=2", "filter.particles=200", "filter.birth_particles=50",
                                     "control.solver=exact"], seed=3)
    cold = engine.run_trial(engine.simulate_trial, "x", 1, 0, s)  # the record with nothing warmed
    calls = []
    real = warmup.warm_up
    monkeypatch.setattr(warmup, "warm_up", lambda sc: (calls.append(sc.name), real(sc)))
    monkeypatch.setattr(engine, "_WARMED", set())
    warm = engine.run_trial(engine.simulate_trial, "table1", 1, 0, s)
    engine.run_trial(engine.simulate_trial, "table1", 1, 1, s)
    engine.run_trial(engine.simulate_trial, "table1", 2, 0, s)
    assert len(calls) == 2  # configurations 1 and 2, once each
    engine.run_trial(lambda sc: {"x": 1.0}, "table1", 3, 0, s)
    assert len(calls) == 2  # a caller's trial function is not ours to warm
    timing = {"step_s_mean", "solve_s_mean", "steps", "experiment", "scenario"}
    assert cold["scenario"] == warm["scenario"]  # the same scenario's fingerprint
    same = [k for k in cold if k not in timing]
    assert same and all(np.array_equal(np.asarray(cold[k]), np.asarray(warm[k]), equal_nan=True) for k in same)
