"""What a damaged folder, a wrong address or a killed sweep does: one line or a clean re-run,
never a traceback, a hang, a lost trial or a process left behind."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from sweep_helpers import ENV, SWEEP, free_port, kill, killed_trial, start, wait_for_files

from trackjam.config import load_scenario
from trackjam.errors import ConfigError
from trackjam.experiments.backends import check_dask_scheduler, parse_scheduler_address
from trackjam.experiments.engine import run_experiment, summarise_folder
from trackjam.experiments.summary import DamagedTrial, parse_trial_filename, read_trial, trial_filename


@pytest.fixture(scope="module")
def fresh(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("fresh")
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    return out


def test_trial_file_names_round_trip_and_nothing_else_parses():
    assert parse_trial_filename(trial_filename(3, 17)) == (3, 17)
    for name in ("copy-of-c01-t0000.parquet", "c01-t0000.parquet.bak", "c1-t0000.parquet",
                 "c01-t0000 (1).parquet", "C01-t0000.parquet", "c01-t00001.parquet"):
        assert parse_trial_filename(name) is None, name


def test_damaged_trials_are_run_again_and_strangers_are_ignored(fresh, tmp_path, capsys):
    out = tmp_path / "resume"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    trials = out / "trials"
    good = (trials / "c01-t0000.parquet").read_bytes()
    (trials / "c01-t0001.parquet").write_bytes(good[: len(good) // 2])  # truncated
    (trials / "c02-t0000.parquet").write_bytes(b"")  # empty
    (trials / "c02-t0001.parquet").write_bytes(good)  # intact, but another trial's record
    (trials / "copy-of-c01.parquet").write_bytes(good)
    (trials / "notes.txt").write_text("mine")

    r = run_experiment("constraints", workers=1, out=out, **{**SWEEP, "progress": "lines"})
    err = capsys.readouterr().err.splitlines()
    assert r.ran == 3
    assert (out / "summary.csv").read_bytes() == (fresh / "summary.csv").read_bytes()
    assert err == [f"constraints: {line}" for line in r.notes] and len(err) == 2
    assert err[0].startswith("constraints: 3 damaged trial file(s)") and "c02-t0000.parquet" in err[0]
    assert "ignoring 2 file(s)" in err[1] and "copy-of-c01.parquet" in err[1] and "notes.txt" in err[1]
    assert (trials / "copy-of-c01.parquet").read_bytes() == good  # not ours: left alone
    assert (trials / "notes.txt").read_text() == "mine"
    for key in ((1, 1), (2, 0), (2, 1)):
        assert read_trial(trials / trial_filename(*key))["trial"] == key[1]
    assert summarise_folder(out).summary == r.summary


def test_a_note_naming_files_is_one_line_without_control_characters(fresh, tmp_path, capsys):
    """File names in trials/ come from anywhere: a newline split the note, an escape sequence
    reached the terminal (error lines escape them already)."""
    out = tmp_path / "e"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    (out / "trials" / "a\nb").write_text("")
    (out / "trials" / "\x1b[31mred").write_text("")
    run_experiment("constraints", workers=1, out=out, **{**SWEEP, "progress": "lines"})
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "\x1b" not in err
    assert "ignoring 2 file(s)" in err and r"\x1b[31mred" in err and r"a\nb" in err


def test_only_an_interrupted_trial_write_is_removed_on_resume(fresh, tmp_path):
    """A leftover of a trial's atomic write is removed; a user's dot file that merely holds
    ".tmp" was deleted, and a folder named like a leftover stopped the resume ("Is a directory")."""
    out = tmp_path / "e"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    trials = out / "trials"
    leftover = trials / ".c01-t0000.parquet.k2j4x9.tmp.parquet"
    leftover.write_bytes(b"half")
    (trials / ".notes.tmp").write_text("mine")
    (trials / ".c02-t0001.parquet.abc.tmp.parquet").mkdir()
    r = run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert r.ran == 0 and not leftover.exists()
    assert (trials / ".notes.tmp").read_text() == "mine" and (trials / ".c02-t0001.parquet.abc.tmp.parquet").is_dir()
    assert (out / "summary.csv").read_bytes() == (fresh / "summary.csv").read_bytes()


def test_a_leftover_that_cannot_be_removed_does_not_stop_a_finished_sweep(fresh, tmp_path, monkeypatch):
    """A finished sweep whose trials/ is read-only (archived) and holds an interrupted write's
    leftover: removing it was an error ("Permission denied") and nothing was summarised."""
    out = tmp_path / "e"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    leftover = out / "trials" / ".c01-t0000.parquet.k2j4x9.tmp.parquet"
    leftover.write_bytes(b"half")
    real = Path.unlink

    def read_only(self, missing_ok=False):
        if self.parent == out / "trials":
            raise PermissionError(13, "Permission denied", str(self))
        return real(self, missing_ok=missing_ok)

    monkeypatch.setattr(Path, "unlink", read_only)
    r = run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert r.ran == 0 and leftover.exists()
    assert (out / "summary.csv").read_bytes() == (fresh / "summary.csv").read_bytes()


def test_a_trial_run_with_other_random_streams_is_run_again_and_said_so(fresh, tmp_path, capsys):
    """A folder from an earlier trackjam, whose trials were seeded otherwise, is not mixed in."""
    import pyarrow as pa

    out = tmp_path / "stale"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    path = out / "trials" / "c02-t0001.parquet"
    table = pq.read_table(path)
    i = table.column_names.index("seed")
    pq.write_table(table.set_column(i, "seed", pa.array([table.column("seed")[0].as_py() + 1],
                                                        type=table.schema.field("seed").type)), path)
    r = run_experiment("constraints", workers=1, out=out, **{**SWEEP, "progress": "lines"})
    err = capsys.readouterr().err.splitlines()
    assert r.ran == 1 and len(err) == 1
    assert "1 trial file(s)" in err[0] and "other random streams" in err[0] and "c02-t0001.parquet" in err[0]
    assert (out / "summary.csv").read_bytes() == (fresh / "summary.csv").read_bytes()


@pytest.mark.parametrize("other", [{"steps": 4}, {"overrides": ["filter.birth_speed=1"]}])
def test_a_trial_copied_from_a_run_with_other_steps_or_set_is_run_again_and_said_so(fresh, tmp_path, capsys, other):
    """Same experiment, seed, configuration and trial, so the same seed column: the trial's
    settings are what differ. It was read back as this run's and mixed into summary.csv."""
    out, elsewhere = tmp_path / "mine", tmp_path / "other"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    run_experiment("constraints", workers=1, out=elsewhere, **{**SWEEP, **other})
    name = trial_filename(2, 1)
    (out / "trials" / name).write_bytes((elsewhere / "trials" / name).read_bytes())
    r = run_experiment("constraints", workers=1, out=out, **{**SWEEP, "progress": "lines"})
    err = capsys.readouterr().err.splitlines()
    assert r.ran == 1 and len(err) == 1
    assert "1 trial file(s)" in err[0] and "other settings" in err[0] and name in err[0]
    assert (out / "summary.csv").read_bytes() == (fresh / "summary.csv").read_bytes()
    assert (out / "paired.csv").read_bytes() == (fresh / "paired.csv").read_bytes()


def test_reading_a_damaged_trial_names_the_file():
    with pytest.raises(DamagedTrial, match="c01-t0000.parquet"):
        read_trial(Path("/nonexistent/c01-t0000.parquet"))


@pytest.mark.parametrize("content", [b"", b"{\"experiment\": ", b"\xff\xfe\x00", b"[1, 2]",
                                     b"[" * 100_000 + b"]" * 100_000])  # deeper than the parser recurses
def test_an_unreadable_experiment_json_is_one_line_and_changes_nothing(fresh, tmp_path, content):
    out = tmp_path / "exp"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    (out / "experiment.json").write_bytes(content)
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    with pytest.raises(ConfigError, match="experiment.json is .*remove the whole folder to start over") as err:
        run_experiment("constraints", workers=1, out=out, **SWEEP)
    assert "\n" not in str(err.value) and str(err.value).startswith(f"--out {out}: experiment.json is ")
    with pytest.raises(ConfigError) as err:  # no option here: the file's path begins the line
        summarise_folder(out)
    assert str(err.value).startswith(f"{out / 'experiment.json'}: ")
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_experiment_json_is_written_whole(fresh):
    params = json.loads((fresh / "experiment.json").read_text())
    assert params["experiment"] == "constraints" and params["seed"] == SWEEP["seed"]
    assert not list(fresh.glob(".*"))


def test_out_pointing_at_a_file_is_one_line_and_exit_2(tmp_path):
    target = tmp_path / "a-file"
    target.write_text("keep me")
    for out in (target, target / "below"):
        with pytest.raises(ConfigError, match="is a file, not a folder") as err:
            run_experiment("constraints", workers=1, out=out, **SWEEP)
        assert "\n" not in str(err.value)
    proc = subprocess.run(
        [sys.executable, "-m", "trackjam", "experiment", "constraints", "--trials", "1", "--out", str(target)],
        capture_output=True, text=True, env=ENV, timeout=120,
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "is a file, not a folder" in proc.stderr
    assert target.read_text() == "keep me"


# --- --scheduler at something that is not a Dask scheduler --------------------------------------


class _FakeServer:
    """A TCP server on 127.0.0.1 that greets like SSH, answers like HTTP, or says nothing."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.conns: list[socket.socket] = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            if self.kind == "ssh":
                conn.sendall(b"SSH-2.0-OpenSSH_9.2p1 Debian-2\r\n")
            elif self.kind == "http":  # answers whatever arrives, like a confused web server
                threading.Thread(target=self._http, args=(conn,), daemon=True).start()

    @staticmethod
    def _http(conn: socket.socket) -> None:
        try:
            if conn.recv(1024):
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
        except OSError:
            pass

    def close(self) -> None:
        self.sock.close()
        for c in self.conns:
            c.close()


@pytest.mark.parametrize("kind, words", [
    ("ssh", "does not speak Dask's protocol"),
    ("http", "sent no Dask handshake within"),
    ("silent", "sent no Dask handshake within"),
])
def test_a_scheduler_address_that_speaks_something_else_is_refused_before_anything_is_written(kind, words, tmp_path):
    server = _FakeServer(kind)
    try:
        with pytest.raises(ConfigError, match=words) as err:
            run_experiment("constraints", scheduler=server.address, out=tmp_path / "out", **SWEEP)
    finally:
        server.close()
    assert "\n" not in str(err.value) and server.address in str(err.value)
    assert not (tmp_path / "out").exists()


def test_a_pre_flight_times_out_on_a_silent_port():
    server = _FakeServer("silent")
    try:
        with pytest.raises(ConfigError, match="within 0.3 s"):
            check_dask_scheduler(server.address, timeout_s=0.3)
    finally:
        server.close()


@pytest.mark.parametrize("address", ["notanaddress", "tcp://host", "tcp://host:99999", "host:port", ""])
def test_a_malformed_scheduler_address_is_refused(address):
    with pytest.raises(ConfigError, match="not an address of the form tcp://HOST:PORT"):
        parse_scheduler_address(address)


@pytest.mark.parametrize("address", ["tcp://sched..local:8786", f"tcp://{'a' * 64}.local:8786", "tcp://.sched:8786"])
def test_a_host_name_that_cannot_be_looked_up_is_refused_up_front(address, tmp_path):
    # a typo (an empty label) or a label past 63 characters made the name lookup raise a
    # UnicodeError (the idna codec): a traceback, once the scenarios were built
    host = address[len("tcp://"):].rsplit(":", 1)[0]
    with pytest.raises(ConfigError, match=rf"^--scheduler '{re.escape(address)}': host '{re.escape(host)}' is not a valid host name"):
        parse_scheduler_address(address)
    with pytest.raises(ConfigError, match="is not a valid host name"):
        run_experiment("constraints", scheduler=address, out=tmp_path / "e", **SWEEP)
    assert not (tmp_path / "e").exists()


def test_scheduler_addresses_parse():
    assert parse_scheduler_address("tcp://10.0.0.5:8786") == ("tcp", "10.0.0.5", 8786)
    assert parse_scheduler_address("sched.local:8786") == ("tcp", "sched.local", 8786)
    assert parse_scheduler_address("tls://[::1]:8786") == ("tls", "::1", 8786)


def test_the_cli_with_a_bad_address_prints_one_line_and_no_traceback(tmp_path):
    for address in ("notanaddress", f"tcp://127.0.0.1:{free_port()}"):
        proc = subprocess.run(
            [sys.executable, "-m", "trackjam", "experiment", "constraints", "--trials", "1", "--steps", "2",
             "--scheduler", address, "--out", str(tmp_path / "out")],
            capture_output=True, text=True, env=ENV, timeout=120,
        )
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.startswith("trackjam: error: ") and proc.stderr.count("\n") == 1, proc.stderr
        assert not (tmp_path / "out").exists()


def test_a_name_lookup_that_does_not_answer_is_one_line_within_the_timeout(tmp_path, monkeypatch):
    # getaddrinfo takes no timeout: a slow or unreachable DNS server held the pre-flight as long as it liked
    pytest.importorskip("distributed")  # imported here, so that the timing below is the lookup's
    from typer.testing import CliRunner

    from trackjam import cli
    from trackjam.experiments import backends

    release, answered = threading.Event(), threading.Event()

    def silent_lookup(*args, **kwargs):  # never the real one: nothing is looked up, not even localhost
        release.wait(60)
        answered.set()
        raise socket.gaierror(socket.EAI_AGAIN, "Temporary failure in name resolution")

    monkeypatch.setattr(backends.socket, "getaddrinfo", silent_lookup)
    monkeypatch.setattr(backends, "CONNECT_TIMEOUT_S", 0.3)
    address = f"tcp://localhost:{free_port()}"
    line = (f"--scheduler '{address}': the name lookup of host 'localhost' did not answer within 0.3 s "
            "(a slow or unreachable DNS server?); try again, or give its IP address")
    try:
        with pytest.raises(ConfigError) as err:
            check_dask_scheduler(address, timeout_s=0.3)
        # the lookup has not answered (it answers only once released): the check gave up on it
        assert not answered.is_set(), "the lookup was waited on past the timeout"
        assert str(err.value) == line
        r = CliRunner().invoke(cli.app, ["experiment", "constraints", "--trials", "1", "--steps", "2",
                                         "--scheduler", address, "--out", str(tmp_path / "out")])
        assert not answered.is_set(), "the sweep waited on the lookup"
    finally:
        release.set()  # the lookups left behind end now
    assert r.exit_code == 2, r.output
    assert r.stderr == f"trackjam: error: {line}\n"
    assert not (tmp_path / "out").exists()


# --- a killed sweep leaves no process behind -----------------------------------------------------


def _children(pid: int) -> set[int]:
    """Every live descendant of ``pid`` (Linux /proc)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            fields = stat.rsplit(")", 1)[1].split()
            if fields[0] != "Z":
                parents[int(entry.name)] = int(fields[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in parents.items() if pp in frontier} - found
        found |= frontier
    return found


def _alive(pids: set[int]) -> set[int]:
    out = set()
    for p in pids:
        try:
            state = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            out.add(p)
    return out


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc to list processes")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_killing_a_sweep_leaves_no_worker_behind(sig, tmp_path):
    out = tmp_path / "sweep"
    # 2 x 12 trials of 1 s on 2 workers: about 12 s of sweep left when the first file is in, so a
    # test process that the loaded machine stalls for a few seconds still signals a running sweep
    # (with 2 x 4 trials, a CI run once signalled a sweep that had already finished: exit status 0)
    trials = 12
    proc = start(["-m", "sweep_helpers", "constraints", str(out), "2", str(trials)],
                 env={**ENV, "TRACKJAM_FAKE_SLEEP": "1"})
    workers: set[int] = set()
    try:
        wait_for_files(out / "trials", 1, proc, limit_s=120)
        assert proc.poll() is None, "the sweep ended before it could be interrupted"
        workers = _children(proc.pid)
        assert len(workers) >= 2  # the pool's two workers (and multiprocessing's helper)
        os.kill(proc.pid, sig)
        proc.wait(timeout=60)
        t0 = time.monotonic()
        while _alive(workers) and time.monotonic() - t0 < 30:  # a guard against a hang
            time.sleep(0.1)
        assert not _alive(workers), f"left behind: {_alive(workers)}"
        if sig == signal.SIGTERM:
            assert proc.returncode == 128 + signal.SIGTERM
    finally:
        for p in _alive(workers):
            os.kill(p, signal.SIGKILL)
        kill(proc)
    # whatever was written is whole, and the sweep resumes to the uninterrupted result
    kept = list((out / "trials").glob("c*.parquet"))
    assert all(pq.read_table(p).num_rows == 1 for p in kept)
    r = run_experiment("constraints", workers=1, out=out, **{**SWEEP, "trials": trials})
    fresh = run_experiment("constraints", workers=1, out=tmp_path / "fresh", **{**SWEEP, "trials": trials})
    assert r.notes == [] and r.ran == 2 * trials - len(kept) and r.summary == fresh.summary


def test_a_scheduler_without_workers_is_said_not_waited_on_in_silence(capsys, monkeypatch):
    """Also: the scheduler's host name is looked up once, by the bounded pre-flight; the client
    connects to the IP address that answered and looks nothing up again."""
    from trackjam.experiments.backends import open_executor

    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = start(["-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
                       address.rsplit(":", 1)[1], "--no-dashboard"])
    try:
        t0 = time.monotonic()
        while True:  # wait until it listens
            try:
                check_dask_scheduler(address, timeout_s=2)
                break
            except ConfigError:
                assert time.monotonic() - t0 < 60, "the scheduler did not start"
                time.sleep(0.3)
        looked_up = []
        real = socket.getaddrinfo

        def spy(host, *args, **kwargs):
            looked_up.append(host)
            return real(host, *args, **kwargs)

        monkeypatch.setattr(socket, "getaddrinfo", spy)
        named = f"tcp://localhost:{port}"
        with open_executor(None, named):
            pass
    finally:
        kill(scheduler)
    assert looked_up.count("localhost") == 1, looked_up
    err = capsys.readouterr().err
    assert err == f"trackjam: the Dask scheduler at {named} has no workers yet; the trials wait for one\n"


def test_a_trial_file_without_a_fingerprint_is_taken_on_its_seed(fresh, tmp_path, capsys):
    """Trial files of a trackjam that wrote no fingerprint (the committed sweeps) are read back,
    not run again: only a fingerprint that differs marks a file of other settings."""
    out = tmp_path / "old"
    run_experiment("constraints", workers=1, out=out, **SWEEP)
    for p in (out / "trials").iterdir():
        table = pq.read_table(p)
        pq.write_table(table.drop_columns(["scenario"]), p)
    r = run_experiment("constraints", workers=1, out=out, **{**SWEEP, "progress": "lines"})
    assert r.ran == 0 and capsys.readouterr().err == ""
    assert (out / "summary.csv").read_bytes() == (fresh / "summary.csv").read_bytes()


def test_the_fingerprint_counts_only_what_differs_from_the_defaults():
    from trackjam.experiments.engine import scenario_digest

    s = load_scenario("paper-fig3")
    assert scenario_digest(s) == scenario_digest(load_scenario("paper-fig3", ["control.lead=0"]))
    assert scenario_digest(s) != scenario_digest(load_scenario("paper-fig3", ["control.lead=0.5"]))
    assert scenario_digest(s) != scenario_digest(load_scenario("paper-fig3", steps=29))


@pytest.mark.parametrize("change, words", [
    ({"trials": 10**9}, "past the cap of 20,000"),  # it built scenarios until the memory ran out
    ({"trials": -1}, "--trials must be a positive integer"),  # KeyError: (1, 0)
    ({"seed": -5}, "--seed -5: must be an integer in [0, 2^63 - 1]"),
    ({"overrides": [1]}, "overrides must be --set items"),  # AttributeError: 'int' object has no attribute 'partition'
])
def test_summarising_a_folder_holds_its_parameters_to_a_sweeps_bounds(fresh, tmp_path, change, words):
    out = tmp_path / "exp"
    shutil.copytree(fresh, out)
    meta = out / "experiment.json"
    meta.write_text(json.dumps({**json.loads(meta.read_text()), **change}))
    with pytest.raises(ConfigError) as err:
        summarise_folder(out)
    assert words in str(err.value) and str(err.value).startswith(f"{meta}: ")


@pytest.mark.parametrize("kwargs, error, words", [
    ({"name": None}, TypeError, "name: expected an experiment's name"),
    ({"trial": 5}, TypeError, "trial: expected a function of a scenario"),
    ({"out": 5}, TypeError, "out: expected a folder's path as text"),
    ({"out": "a\x00b"}, ValueError, "out: holds a NUL character, which no path may"),
    ({"out": b"e"}, TypeError, "out: expected a folder's path as text, got bytes"),
    ({"out": ""}, ValueError, "out: expected a folder's path, got an empty text"),
    # object of type 'int' has no len(); AttributeError: 'int' object has no attribute 'strip'
    ({"scheduler": 5}, TypeError, "scheduler: expected an address as text"),
    ({"name": "swarm", "grid": 5}, TypeError, "grid: expected TARGETSxAGENTS as text"),
    # read a character at a time ("--set 's': expected key=value"); AttributeError: 'int' object
    # has no attribute 'partition'
    ({"overrides": "steps=3"}, ConfigError, "overrides: a list of 'key=value' texts"),
    ({"overrides": [5]}, ConfigError, "overrides: a list of 'key=value' texts"),
    ({"overrides": {"antenna.r0=3"}}, ConfigError, "overrides: a list of 'key=value' texts, in order"),
])
def test_run_experiment_names_an_argument_of_the_wrong_kind(tmp_path, kwargs, error, words):
    args = {"name": "constraints", "trials": 1, "steps": 2, "workers": 1, "out": tmp_path / "e"} | kwargs
    name = args.pop("name")
    with pytest.raises(error) as err:
        run_experiment(name, **args)
    assert str(err.value).startswith(words)
    assert not (tmp_path / "e").exists()


def test_run_experiment_takes_numpy_integers(tmp_path):
    import numpy as np

    # --seed np.int64(1) was "--seed 1: must be an integer"
    r = run_experiment("constraints", trials=np.int64(1), steps=np.int32(2), seed=np.int64(1), workers=1,
                       out=tmp_path / "e", progress="none")
    assert r.ran == 2 and json.loads((tmp_path / "e" / "experiment.json").read_text())["seed"] == 1


def test_summarising_a_folder_without_an_intact_trial_is_one_line(fresh, tmp_path):
    # it wrote tables of NaN without a word
    out = tmp_path / "exp"
    shutil.copytree(fresh, out)
    for p in (out / "trials").iterdir():
        p.write_bytes(b"")
    before = (out / "summary.csv").read_bytes()
    with pytest.raises(ConfigError, match=r"trials: no intact trial of this experiment, nothing to summarise \(4 damaged"):
        summarise_folder(out)
    assert (out / "summary.csv").read_bytes() == before


def test_a_rerun_removes_what_killed_writes_of_the_results_left_at_the_top(tmp_path):
    # a SIGKILL while the figure was written left .fig5.png.<random>.tmp.png, and it stayed
    # after a successful rerun (the leftovers in trials/ were removed)
    out = tmp_path / "e"
    run_experiment("constraints", trials=1, steps=2, workers=1, out=out, progress="none")
    left = [out / ".fig5.png.m4kupqju.tmp.png", out / ".summary.csv.ab12cd34.tmp.csv",
            out / ".experiment.json.zz99yy88.tmp.json"]
    for p in left:
        p.write_bytes(b"half")
    mine = [out / ".notes", out / ".fig5.png.backup"]  # a user's dot files are not ours
    for p in mine:
        p.write_text("keep")
    r = run_experiment("constraints", trials=1, steps=2, workers=1, out=out, progress="none")
    assert r.ran == 0
    assert not any(p.exists() for p in left)
    assert all(p.read_text() == "keep" for p in mine)


def test_a_lost_scheduler_is_one_line_and_the_trials_written_resume(tmp_path):
    # a scheduler killed mid-sweep: Dask's client logged its reconnection tracebacks and the
    # sweep ended in a CancelledError traceback, exit status 1
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    sched = start(["-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", str(port),
                   "--no-dashboard"])
    worker = start(["-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--no-dashboard", "--no-nanny"])
    out = tmp_path / "e"
    try:
        from distributed import Client

        client = Client(address, timeout=30)
        client.wait_for_workers(1, timeout=60)
        client.close()
        p = subprocess.Popen([sys.executable, "-m", "trackjam", "experiment", "constraints", "--trials", "4", "--steps",
                              "10", "--scheduler", address, "--out", str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        wait_for_files(out / "trials", 1, p, limit_s=120)
        kill(sched)
        _, err = p.communicate(timeout=120)
    finally:
        kill(worker)
        kill(sched)
    assert p.returncode == 2, err
    assert "Traceback" not in err and "ERROR" not in err, err
    errors = [line for line in err.splitlines() if line.startswith("trackjam: error")]
    assert len(errors) == 1 and re.fullmatch(
        rf"trackjam: error: --scheduler {re.escape(address)}: lost the Dask scheduler \(\w+\); the trials written are "
        r"intact: run the same command again to resume", errors[0]), err
    written = len(list((out / "trials").glob("c*.parquet")))
    assert written >= 1
    r = run_experiment("constraints", trials=4, steps=10, workers=1, out=out, progress="none")
    assert r.ran == 8 - written


def test_a_worker_killed_from_outside_is_one_line_and_a_rerun_resumes(tmp_path, monkeypatch):
    """The out-of-memory killer or a `kill -9` on a pool worker: an 86-line BrokenProcessPool
    traceback, exit status 1; now one line naming what happened, the trials written intact."""
    from trackjam.errors import OutputError

    out = tmp_path / "sweep"
    monkeypatch.setenv("TRACKJAM_KILL_TRIAL", "1")
    with pytest.raises(OutputError, match=r"^a worker process of the pool ended abruptly \(killed from outside, "
                       r"perhaps by the system for lack of memory, or failing as it started: see above\); the trials "
                       r"written are intact: run the same command again to resume"):
        run_experiment("constraints", workers=2, out=out, **{**SWEEP, "trials": 3, "trial": killed_trial})
    written = sorted(p.name for p in (out / "trials").glob("c*.parquet"))
    assert "c02-t0001.parquet" not in written
    monkeypatch.delenv("TRACKJAM_KILL_TRIAL")
    r = run_experiment("constraints", workers=1, out=out, **SWEEP | {"trials": 3, "trial": killed_trial})  # resumes
    assert len(list((out / "trials").glob("c*.parquet"))) == 6 and r is not None


def test_a_script_without_a_main_guard_is_told_to_add_one(tmp_path):
    """Each spawned worker imports the parent's script again: without `if __name__ ==
    "__main__":` every worker started a sweep of its own and failed on the parent's lock ("another
    sweep is writing there"), and the parent blamed a worker "killed from outside"."""
    script = tmp_path / "noguard.py"
    script.write_text(
        "from sweep_helpers import SWEEP\n"
        "from trackjam.experiments.engine import run_experiment\n"
        f"run_experiment('constraints', workers=2, out={str(tmp_path / 'out')!r}, **SWEEP)\n"
    )
    r = subprocess.run([sys.executable, str(script)], env=ENV, capture_output=True, text=True, timeout=300)
    assert r.returncode != 0
    assert "put the call under `if __name__ == \"__main__\":`" in r.stderr
    assert "another sweep is writing there" not in r.stderr
