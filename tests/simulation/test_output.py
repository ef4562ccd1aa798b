"""`trackjam run`: the output folder, its files, and refusing to overwrite what is not ours."""

import contextlib
import fcntl
import json
import os
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from trackjam.config import load_scenario
from trackjam.errors import ConfigError, OutputError
from trackjam.simulation.output import check_out_dir

FAST = ["steps=4", "control.solver=exact", "filter.particles=500", "filter.birth_particles=200"]


def trackjam(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "trackjam", *args], capture_output=True, text=True, cwd=cwd)


def sets(items):
    return [a for it in items for a in ("--set", it)]


def test_run_writes_every_file(tmp_path):
    out = tmp_path / "run"
    r = trackjam("run", "paper-fig3", "--out", str(out), *sets(FAST))
    assert r.returncode == 0, r.stderr
    for name in ["scenario.yaml", "summary.json", "steps.parquet", "agents.parquet", "measurements.parquet", "run.png", "replay.html"]:
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 1 and "version" in summary and len(summary["jamming_incidents"]) == 3
    steps = pq.read_table(out / "steps.parquet").to_pydict()
    assert steps["t"] == [1, 2, 3, 4]
    assert np.mean(steps["ospa"]) == pytest.approx(summary["ospa_mean"])
    assert "mean OSPA" in r.stdout  # the closing table
    # its track quality is the summary's, judged by the truth, never "existence > 0.5"
    n = summary["detectable_steps"]
    assert "held (confirmed, within 5 m) / detectable steps" in r.stdout
    assert f"{summary['held_steps']}/{n}" in r.stdout and f"{summary['missed_steps']}/{n}" in r.stdout
    assert "ceiling: a chaser within 8 m" in r.stdout and "existence > 0.5" not in r.stdout
    assert steps["quality"].count("held") == summary["held_steps"]
    assert "step 4/4" in r.stdout  # one plain line per step when not on a terminal
    # the same scenario again into the same folder is allowed and reproduces the logs
    r2 = trackjam("run", "paper-fig3", "--out", str(out), *sets(FAST))
    assert r2.returncode == 0, r2.stderr
    assert pq.read_table(out / "steps.parquet").to_pydict()["existence"] == steps["existence"]


def test_out_pointing_at_a_file_is_refused_and_the_file_kept(tmp_path):
    f = tmp_path / "precious.txt"
    f.write_text("keep me")
    r = trackjam("run", "paper-fig3", "--out", str(f), *sets(FAST))
    assert r.returncode == 2 and "is a file" in r.stderr and "Traceback" not in r.stderr
    assert f.read_text() == "keep me"


def test_out_holding_another_scenario_is_refused_and_untouched(tmp_path):
    out = tmp_path / "run"
    assert trackjam("run", "paper-fig3", "--out", str(out), "--no-figures", *sets(FAST)).returncode == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    r = trackjam("run", "paper-fig3", "--out", str(out), "--seed", "5", *sets(FAST))
    assert r.returncode == 2 and "not empty" in r.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_the_same_scenarios_run_beside_other_entries_is_refused_naming_them():
    """An earlier run of this very scenario with a subfolder beside it: the message said "holds
    another scenario's run", although the scenario was the same; it names the other entries."""
    import tempfile

    from trackjam.simulation.build import scenario_text

    s = load_scenario("paper-fig3", list(FAST))
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "run")
        os.makedirs(os.path.join(out, "sub"))
        with open(os.path.join(out, "scenario.yaml"), "w") as f:
            f.write(scenario_text(s))
        with pytest.raises(ConfigError, match=r"folder is not empty and holds other files \(sub\); choose a new"):
            check_out_dir(out, s)


def test_the_default_folder_of_another_run_is_refused_without_blaming_an_untyped_out(tmp_path):
    # `trackjam run paper-fig3`, then the README's `--set antenna.pointing=aim`: the same name and
    # seed, so the same default folder, which holds the first run and is kept
    first = tmp_path / "runs" / "paper-fig3-seed1"
    first.mkdir(parents=True)
    (first / "scenario.yaml").write_text("name: paper-fig3\n")
    r = trackjam("run", "paper-fig3", "--set", "antenna.pointing=aim", *sets(FAST), cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and "--out runs" not in lines[0], lines
    assert "runs/paper-fig3-seed1 (the default output folder, from the scenario's name and seed)" in lines[0]
    assert "another scenario's run; pass --out FOLDER or change the scenario's `name`" in lines[0]
    assert [p.name for p in first.iterdir()] == ["scenario.yaml"]
    # a --out the user typed is named as such
    r = trackjam("run", "paper-fig3", "--out", str(first), *sets(FAST))
    assert r.returncode == 2 and f"--out {first}: folder is not empty" in r.stderr


def test_out_with_foreign_files_is_refused(tmp_path):
    (tmp_path / "notes.md").write_text("mine")
    with pytest.raises(ConfigError, match="not empty"):
        check_out_dir(tmp_path, load_scenario("paper-fig3"))


def test_unwritable_out_is_refused():
    # /sys refuses new files even to root, which plain permission bits would not
    r = trackjam("run", "paper-fig3", "--out", "/sys/trackjam-out", *sets(FAST))
    assert r.returncode == 2 and "no file can be made in" in r.stderr and "Traceback" not in r.stderr


def test_unwritable_out_under_a_file_is_refused(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(ConfigError):
        check_out_dir(f / "sub" / "dir", load_scenario("paper-fig3"))


@pytest.fixture(scope="module")
def small_result():
    from trackjam.simulation.loop import simulate

    return simulate(load_scenario("paper-fig3", FAST))


def test_files_get_the_umasks_mode_not_mkstemps(tmp_path, small_result):
    import os

    from trackjam.simulation.output import write_run

    old = os.umask(0o027)
    try:
        files = write_run(small_result, tmp_path / "a", figures=False)
    finally:
        os.umask(old)
    assert {f.stat().st_mode & 0o777 for f in files} == {0o640}
    old = os.umask(0o002)
    try:
        files = write_run(small_result, tmp_path / "b", figures=False)
    finally:
        os.umask(old)
    assert {f.stat().st_mode & 0o777 for f in files} == {0o664}


def test_what_a_killed_write_leaves_does_not_block_the_rerun_and_is_removed(tmp_path, small_result):
    from trackjam.simulation.output import write_run

    out = tmp_path / "run"
    write_run(small_result, out, figures=False)
    leftover = out / ".run.png.k3j9x_2a.tmp.png"  # what an earlier version's write left when SIGKILLed
    leftover.write_bytes(b"half a png")
    stage = out / ".trackjam-staging.x8q1z0.tmp"  # what this version's leaves: its staging folder
    stage.mkdir()
    (stage / "steps.parquet").write_bytes(b"half a parquet")
    check_out_dir(out, small_result.scenario)
    write_run(small_result, out, figures=False)
    assert not leftover.exists() and not stage.exists()
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["scenario.yaml", "steps.parquet", "agents.parquet", "measurements.parquet", "summary.json"])
    (out / ".notes.tmp.png").write_text("not ours")  # a hidden file of the user's is not ours to ignore
    with pytest.raises(ConfigError, match="not empty"):
        check_out_dir(out, small_result.scenario)
    (out / ".notes.tmp.png").unlink()
    (out / ".trackjam-staging.mine").mkdir()  # nor a folder that is not named as ours
    with pytest.raises(ConfigError, match="not empty"):
        check_out_dir(out, small_result.scenario)


@contextlib.contextmanager
def _holding(out):
    """``out`` locked as a first run that writes into it holds it (simulation/output.py)."""
    fd = os.open(out, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        yield
    finally:
        os.close(fd)


def _second_run_waits(out, result, first_run_ends):
    """A second write_run into ``out`` while a first holds it: it says it waits and waits; once
    ``first_run_ends()`` and the lock is let go it writes its run, whole."""
    import threading
    import time

    from trackjam.simulation.output import write_run

    waited, errors = [], []
    second = threading.Thread(target=lambda: _catch(errors, write_run, result, out, figures=False,
                                                    on_wait=lambda: waited.append(1)))
    with _holding(out):
        second.start()
        time.sleep(1.0)
        assert second.is_alive() and waited == [1]
        first_run_ends()
    second.join(60)
    assert not second.is_alive() and errors == []
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["scenario.yaml", "steps.parquet", "agents.parquet", "measurements.parquet", "summary.json"])


def test_a_second_run_into_one_folder_waits_for_the_first_and_leaves_its_staging_alone(tmp_path, small_result):
    # a second run removed the first one's live staging folder as a leftover, and the first
    # failed ("replay.html: cannot be written (No such file or directory)")
    from trackjam.simulation.output import write_run

    out = tmp_path / "run"
    write_run(small_result, out, figures=False)
    live = out / ".trackjam-staging.live0001.tmp"  # the first run's, while it writes
    live.mkdir()

    def first_run_ends():
        assert live.is_dir()  # the waiting run has removed nothing
        live.rmdir()

    _second_run_waits(out, small_result, first_run_ends)


def test_a_run_waiting_for_a_write_that_fails_and_removes_its_folder_writes_its_own(tmp_path, small_result):
    # the first write's cleanup ran after it let go of the lock: the waiting run found the folder
    # half removed (a false "holds other files", "No such file or directory", a traceback)
    out = tmp_path / "run"
    out.mkdir()  # made by the first run, which holds it
    _second_run_waits(out, small_result, out.rmdir)  # the first run failed: it removes the folder it made, locked


def test_a_ctrl_c_while_waiting_for_the_folder_writes_nothing_and_is_not_said_written(tmp_path, small_result):
    from trackjam.simulation.output import WROTE, write_run

    out = tmp_path / "run"
    write_run(small_result, out, figures=False)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def ctrl_c():
        raise KeyboardInterrupt

    with _holding(out), pytest.raises(KeyboardInterrupt) as err:
        write_run(small_result, out, figures=False, on_wait=ctrl_c)
    assert not getattr(err.value, WROTE, False)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def _catch(errors, fn, *args, **kwargs):
    try:
        fn(*args, **kwargs)
    except BaseException as err:  # noqa: BLE001 (reported by the test's thread)
        errors.append(err)


def test_a_run_of_another_scenario_written_meanwhile_is_kept_and_said(tmp_path, small_result, monkeypatch):
    import trackjam.simulation.output as output
    from trackjam.simulation.loop import simulate

    out = tmp_path / "run"
    other = simulate(load_scenario("paper-fig3", FAST + ["seed=7"]))
    output.write_run(other, out, figures=False)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    check = output.check_out_dir
    calls = []

    def first_before_the_other_run(*args, **kwargs):  # the check at the start saw the folder empty
        calls.append(1)
        if len(calls) > 1:
            check(*args, **kwargs)

    monkeypatch.setattr(output, "check_out_dir", first_before_the_other_run)
    with pytest.raises(ConfigError, match=r"^--out .*: folder is not empty and holds another scenario's run, made there while this run ran "
                       r"\(nothing of this run was written\); choose a new or empty folder$"):
        output.write_run(small_result, out, figures=False)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_full_disk_is_one_line_and_changes_nothing(tmp_path, small_result, monkeypatch):
    import errno

    from typer.testing import CliRunner

    from trackjam import cli
    from trackjam.simulation import logs

    out = tmp_path / "run"
    from trackjam.simulation.output import write_run

    write_run(small_result, out, figures=False)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    real = logs.write_parquet
    calls = []

    def full_disk(table, path):
        calls.append(path)
        if len(calls) == 2:  # agents.parquet, after scenario and steps were written
            with open(path, "wb") as f:
                f.write(b"partial")
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(table, path)

    monkeypatch.setattr(logs, "write_parquet", full_disk)
    r = CliRunner().invoke(cli.app, ["run", "paper-fig3", "--out", str(out), "--no-figures", *sets(FAST)])
    assert r.exit_code == 2, r.output
    lines = [l for l in r.output.splitlines() if l.startswith("trackjam: error")]
    assert len(lines) == 1 and "Traceback" not in r.output
    assert f"agents.parquet: cannot be written (No space left on device); nothing in {out} was changed" in lines[0]
    # every file keeps the earlier run's bytes (it rewrote steps.parquet before the disk filled),
    # and nothing else is left there
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert json.loads(before["summary.json"])["seed"] == 1


def test_markup_in_an_out_path_is_printed_literally_and_the_warm_up_is_announced(tmp_path):
    out = tmp_path / "[/oops]" / "[bold]run"
    r = trackjam("run", "paper-fig3", "--out", str(out), "--no-figures", *sets(FAST))
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr and (out / "steps.parquet").is_file()
    lines = r.stdout.splitlines()
    assert lines[0] == "loading the compiled kernels (compiling them on the first run only, 6-12 s)"
    assert lines[1] == "paper-fig3: step 1/4"
    assert lines[-1] == f"wrote 5 files to {out}"


@pytest.mark.parametrize("parts", [("kept", "a", "b"), ("new", "..", "kept", "run")])
def test_a_full_disk_removes_only_the_folders_the_write_made(tmp_path, small_result, monkeypatch, parts):
    # the folders were found by walking up the path as written: `new/../kept/run` removed `kept`
    import errno

    from trackjam.simulation import logs
    from trackjam.simulation.output import write_run

    def full_disk(table, path):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(logs, "write_parquet", full_disk)
    (tmp_path / "kept").mkdir()
    with pytest.raises(OutputError, match="steps.parquet: cannot be written .*; nothing in .* was changed"):
        write_run(small_result, tmp_path.joinpath(*parts), figures=False)
    assert [p.name for p in tmp_path.iterdir()] == ["kept"] and not any((tmp_path / "kept").iterdir())
