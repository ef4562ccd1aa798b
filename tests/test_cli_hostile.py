"""The command line against a hostile user, beyond the one-target scenario: options the swarm
engine does not read, an output folder holding a binary scenario.yaml, a bench --json into a
folder nobody can write. One line on stderr naming the key or option, exit status 2, no
traceback, nothing written."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from typer.testing import CliRunner

from trackjam.cli import app


def _trackjam(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "trackjam", *args], capture_output=True, text=True, cwd=cwd)


def _one_line(r: subprocess.CompletedProcess) -> str:
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    lines = [line for line in r.stderr.splitlines() if line.strip() and "warning" not in line]
    assert len(lines) == 1, r.stderr
    return lines[0]


@pytest.mark.parametrize(
    "item, key",
    [
        ("fusion.search_reseed=evidence", "fusion.search_reseed"),
        ("control.plan_over=belief", "control.plan_over"),
        ("fusion.existence=evidence", "fusion.existence"),
    ],
)
def test_validate_refuses_what_the_swarm_engine_does_not_simulate_as_run_does(tmp_path, item, key):
    line = _one_line(_trackjam("validate", "swarm-3", "--set", item))
    assert line.startswith(f"trackjam: error: --set {item}: {key}:") and "several targets" in line
    line = _one_line(_trackjam("run", "swarm-3", "--set", item, "--out", str(tmp_path / "out")))
    assert line.startswith(f"trackjam: error: --set {item}: {key}:")
    assert not (tmp_path / "out").exists()


def test_the_same_options_stay_valid_with_one_target():
    r = _trackjam("validate", "paper-fig3", "--set", "fusion.search_reseed=evidence")
    assert r.returncode == 0 and r.stdout.startswith("ok")


@pytest.mark.parametrize("item", ["comms.loss=0.5", "comms.delay_steps=2", "comms.stale=drop",
                                  "comms.failures=[{agent: 0, step: 3, mode: breakdown}]"])
def test_the_comms_faults_are_valid_with_several_targets(item):
    r = _trackjam("validate", "swarm-3", "--set", item)
    assert r.returncode == 0 and r.stdout.startswith("ok"), r.stderr


def test_an_out_folder_holding_a_binary_scenario_yaml_is_refused_and_kept(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "scenario.yaml").write_bytes(b"\xff\xfe\x00binary")
    line = _one_line(_trackjam("run", "paper-fig3", "--set", "steps=1", "--out", str(out)))
    assert "--out" in line and "another scenario's run" in line
    assert (out / "scenario.yaml").read_bytes() == b"\xff\xfe\x00binary"
    assert [p.name for p in out.iterdir()] == ["scenario.yaml"]


# Linux's /proc and /sys refuse a new file even to root, for whom a chmod'ed folder is writable
@pytest.mark.parametrize("folder", ["/proc", "/sys"])
def test_bench_json_into_an_unwritable_folder_is_refused_before_the_benchmarks(folder):
    r = _trackjam("bench", "--only", "env", "--quick", "--json", f"{folder}/bench.json")
    line = _one_line(r)
    assert line.startswith(f"trackjam: error: --json {folder}/bench.json: no file can be made in {folder} (")
    assert "running" not in r.stdout  # refused before a benchmark ran


def test_a_grid_of_non_ascii_digits_is_refused(tmp_path):
    line = _one_line(_trackjam("experiment", "swarm", "--grid", "\u0661x\u0663", "--out", str(tmp_path / "e")))
    assert "--grid" in line and "whole numbers" in line
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize(
    "args",
    [
        ["validate", "{long}.yaml"],
        ["run", "paper-fig3", "--set", "steps=1", "--no-figures", "--out", "{long}"],
        ["experiment", "constraints", "--trials", "1", "--out", "{long}"],
        ["bench", "--only", "env", "--quick", "--json", "{long}.json"],
    ],
)
def test_a_path_name_past_the_systems_limit_is_one_line(tmp_path, args):
    # 300 bytes in one name: even Path.exists() raises, where no check of ours looked; the line
    # shows the path by its two ends (it had held all of it) and names the option that gave it
    from trackjam.errors import ends

    long = str(tmp_path / ("x" * 300))
    line = _one_line(_trackjam(*[a.format(long=long) for a in args]))
    given = next(a.format(long=long) for a in args if "{long}" in a)
    option = args[args.index(next(a for a in args if "{long}" in a)) - 1]
    assert len(line) < 250
    if option.startswith("--"):
        assert line == (f"trackjam: error: {option} {ends(given)}: too long for the file system: a name of "
                        f"{len(given) - len(str(tmp_path)) - 1} bytes, past its 255")
    else:
        assert line == f"trackjam: error: {ends(given)}: File name too long"
    assert list(tmp_path.iterdir()) == []


def test_a_path_past_the_systems_whole_length_is_named_by_its_option(tmp_path):
    deep = str(tmp_path / "/".join(["d" * 200] * 25))
    line = _one_line(_trackjam("run", "paper-fig3", "--out", deep))
    assert line.startswith(f"trackjam: error: --out {deep[:60]}...") and line.endswith(
        f"too long for the file system: {len(deep.encode())} bytes in all, past its 4095")
    assert list(tmp_path.iterdir()) == []


def _fits_but_not_its_files(tmp_path: Path, length: int) -> str:
    """A path of ``length`` bytes, under the system's 4096, of names of 200 bytes at most."""
    head = len(str(tmp_path)) + 1
    names, left = [], length - head
    while left > 201:
        names.append("d" * 200)
        left -= 201
    return str(tmp_path / "/".join([*names, "e" * left]))


@pytest.mark.parametrize("args, under", [
    (["run", "paper-fig3", "--set", "steps=2", "--no-figures"], 52),
    (["experiment", "constraints", "--trials", "1", "--steps", "2", "--workers", "1"], 51),
])
def test_an_out_that_fits_but_whose_files_would_not_is_refused_before_the_work(tmp_path, args, under):
    # an --out of 4060 bytes passed the check, and the run's files in its staging folder (52 bytes
    # more) failed with "File name too long" once every step was done, in a line of 8 kB; a sweep
    # left experiment.json and an empty trials/ and failed at its first trial
    out = _fits_but_not_its_files(tmp_path, 4060)
    r = _trackjam(*args, "--out", out)
    line = _one_line(r)
    assert len(line) < 300 and r.stdout == ""
    assert line.endswith(f": too long for the file system: the files written in it would have a path of "
                         f"{4060 + under} bytes, past its 4095")
    assert list(tmp_path.iterdir()) == []


def test_the_longest_paths_checked_are_those_written():
    from trackjam.cli import EXPERIMENT_UNDER, RUN_UNDER
    from trackjam.experiments.summary import trial_filename
    from trackjam.files import TEMP_MARK, temporary_beside
    from trackjam.simulation.output import RUN_FILES, STAGING

    assert RUN_UNDER == f"{STAGING}{'x' * 8}{TEMP_MARK}/{max(RUN_FILES, key=len)}"
    assert EXPERIMENT_UNDER == f"trials/{temporary_beside(Path(trial_filename(20000, 20000))).name}"


def test_a_bench_json_name_whose_temporary_name_would_not_fit_is_refused_before_the_benchmarks(tmp_path):
    # 245 bytes fit, but atomic_write's temporary name .NAME.XXXXXXXX.tmp.json (269) did not:
    # every benchmark ran, then the write failed
    given = str(tmp_path / ("a" * 240 + ".json"))
    r = _trackjam("bench", "--only", "filter", "--quick", "--json", given)
    assert _one_line(r).endswith(": too long for the file system: its temporary file (written first) would "
                                 "have a name of 264 bytes, past its 255")
    assert r.stdout == "" and list(tmp_path.iterdir()) == []


def test_a_newline_in_out_stays_in_the_one_line_that_says_what_was_written(tmp_path):
    out = tmp_path / "new\nline"
    r = _trackjam("run", "paper-fig3", "--set", "steps=2", "--no-figures", "--out", str(out))
    assert r.returncode == 0
    assert r.stdout.splitlines()[-1] == f"wrote 5 files to {tmp_path}/new\\nline"


@pytest.mark.parametrize("args", [["show-config", "swarm-3"], ["presets"], ["validate", "paper-fig3"],
                                  # written before any command runs: they were OSError tracebacks, exit 1
                                  ["--version"], ["--help"], ["bench", "--help"], ["run", "--help"], []])
def test_an_output_on_a_full_disk_is_one_line(args):
    # /dev/full: every write fails with ENOSPC, as a redirect to a full disk does
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "trackjam", *args], stdout=full, stderr=subprocess.PIPE, text=True)
    assert _one_line(r) == "trackjam: error: cannot write the output: No space left on device"


def test_a_failure_after_the_last_step_warns_in_one_line_and_validate_says_ok():
    r = _trackjam("validate", "paper-fig3", "--set",
                  "comms.failures=[{agent: 0, step: 5, mode: breakdown}, {agent: 1, step: 31, mode: channel}]")
    assert r.returncode == 0 and r.stdout.startswith("ok"), r.stderr
    assert r.stderr.splitlines() == [
        "trackjam: warning: comms.failures[1]: start after the last step (30); the agent never fails"]


def _numba_interrupt(*args, **kwargs):
    """What a SIGINT looks like when its handler runs inside a callback of compiled numba code."""
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as err:
        raise SystemError("CPUDispatcher(<function kernel>) returned a result with an exception set") from err


def test_a_ctrl_c_that_numba_turned_into_a_system_error_is_an_interrupt(monkeypatch, tmp_path):
    import trackjam.simulation.loop as loop

    monkeypatch.setattr(loop, "simulate", _numba_interrupt)
    out = tmp_path / "r"
    r = CliRunner().invoke(app, ["run", "paper-fig3", "--set", "steps=2", "--out", str(out)])
    assert r.exit_code == 130 and "trackjam: interrupted" in r.output and "Traceback" not in r.output
    assert not out.exists()


def test_only_a_system_error_caused_by_ctrl_c_counts_as_an_interrupt():
    from trackjam.cli import interrupted

    with pytest.raises(SystemError) as info:
        _numba_interrupt()
    assert interrupted(info.value) and interrupted(KeyboardInterrupt())
    assert not interrupted(SystemError("a real bug")) and not interrupted(ValueError())


LONG = "9" * 5000  # past Python's 4300 digits: int() raised ValueError inside the parsers


def test_an_integer_of_thousands_of_digits_in_a_set_is_one_line():
    line = _one_line(_trackjam("validate", "paper-fig3", "--set", f"steps={LONG}"))
    assert line == f"trackjam: error: --set steps={LONG[:51]}...: steps: integer too large (5000 digits)"


@pytest.mark.parametrize("name, text, where", [
    ("long.yaml", f"steps: {LONG}\n", "steps: integer too large (5000 digits)"),
    ("long.toml", f"steps = {LONG}\n", "steps: integer too large (5000 digits, line 1)"),
])
def test_an_integer_of_thousands_of_digits_in_a_file_is_one_line(tmp_path, name, text, where):
    f = tmp_path / name
    f.write_text(text)
    assert _one_line(_trackjam("validate", str(f))) == f"trackjam: error: {f}: {where}"


def test_a_grid_of_thousands_of_digits_is_refused(tmp_path):
    line = _one_line(_trackjam("experiment", "swarm", "--grid", f"{LONG}x3", "--out", str(tmp_path / "e")))
    assert line == f"trackjam: error: --grid: targets '{LONG[:37]}...' must lie within 1..8, low to high"
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("seed", ["99999999999999999999999", str(2**63), "-1"])
def test_an_experiment_seed_out_of_range_is_refused_as_run_refuses_it(tmp_path, seed):
    # SeedSequence took any size: run refused 2^63, experiment ran it
    line = _one_line(_trackjam("experiment", "table1", "--trials", "1", "--steps", "3", "--seed", seed,
                               "--out", str(tmp_path / "e")))
    assert line == f"trackjam: error: --seed {seed}: must be an integer in [0, 2^63 - 1]"
    assert not (tmp_path / "e").exists()


def test_a_malformed_flow_mapping_in_a_set_is_named_as_yaml(tmp_path):
    line = _one_line(_trackjam("run", "paper-fig3", "--set", "filter.cue={existence: 1", "--out", str(tmp_path / "r")))
    assert line == ("trackjam: error: --set filter.cue={existence: 1: not valid YAML: expected ',' or '}', "
                    "but got '<stream end>' (column 14)")
    assert not (tmp_path / "r").exists()


def test_a_scenario_file_of_another_extension_is_refused(tmp_path):
    f = tmp_path / "scenario.txt"
    f.write_text("steps: 3\n")
    line = _one_line(_trackjam("validate", str(f)))
    assert line == (f"trackjam: error: {f}: unknown extension '.txt': a scenario file ends in .yaml, .yml or .toml "
                    "(any case)")


def test_planning_over_a_belief_too_large_for_a_step_is_refused_before_the_run(tmp_path):
    agents = "agents.initial=[" + ",".join("[%d,%d,30]" % (5 + i % 6 * 15, 5 + i // 6 * 15) for i in range(32)) + "]"
    sets = ["--set", "steps=1", "--set", agents, "--set", "control.belief_samples=256", "--set",
            "control.belief_spread=null", "--set", "target.occlusions=[]"]
    for command in (["validate", "pursuit"], ["run", "pursuit", "--no-figures", "--out", str(tmp_path / "r")]):
        line = _one_line(_trackjam(*command, *sets))
        assert line == ("trackjam: error: --set control.belief_samples=256: control.belief_samples: one step would "
                        "take about 8.4e+09 operations (belief), past the cap of 1e+09; lower control.belief_samples")
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("mode", ["filter.mode={radius: 1e-5, mass: 0.2}", "filter.mode.radius=1e-9"])
def test_a_tiny_mode_radius_runs(tmp_path, mode):
    # the mode's grid counted 1e7 cells a side in int64, overflowed, and numpy refused a negative size
    sets = ["steps=3", "target.occlusions=[]", "filter.particles=300", "filter.birth_particles=60", mode]
    r = _trackjam("run", "pursuit", *[a for item in sets for a in ("--set", item)], "--no-figures",
                  "--out", str(tmp_path / "r"))
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert (tmp_path / "r" / "summary.json").is_file()


def test_a_swarm_figure_with_a_long_target_id_writes_no_raw_warning(tmp_path):
    ids = "targets=[{id: %s}, {id: b}, {id: c}]" % ("a" * 100)
    r = _trackjam("run", "swarm-3", "--set", "steps=3", "--set", ids, "--set", "filter.particles=100",
                  "--set", "filter.birth_particles=20", "--out", str(tmp_path / "r"))
    assert r.returncode == 0 and r.stderr == "", r.stderr  # was matplotlib's "constrained_layout not applied"
    assert (tmp_path / "r" / "run.png").is_file()


def test_a_run_figure_of_many_agents_writes_no_raw_warning(tmp_path):
    import warnings

    from trackjam.config import load_scenario
    from trackjam.simulation.build import figure_settings
    from trackjam.simulation.loop import simulate
    from trackjam.viz.figure import plot_run

    agents = "agents.initial=[" + ",".join("[%d,%d,%d]" % (5 + i % 4 * 25, 5 + i // 4 % 4 * 25, 10 + i // 16 * 20)
                                           for i in range(32)) + "]"
    s = load_scenario("paper-fig3", ["steps=1", agents, "control.solver=greedy", "filter.particles=50",
                                     "filter.birth_particles=10", "target.occlusions=[]", "agents.n_inclination=2",
                                     "agents.n_azimuth=2", "agents.radial_steps=[1]"])
    r = simulate(s)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plot_run(r.steps, r.agents, figure_settings(s), tmp_path / "run.png")
    assert [str(w.message) for w in caught] == []  # the legends of 32 agents left a panel no room
    assert (tmp_path / "run.png").stat().st_size > 0


@pytest.mark.parametrize("command", ["run", "validate"])
def test_a_refused_command_prints_its_one_line_and_no_warning(tmp_path, command):
    """Suspicious values (a 1 deg cone; for paper-fig3 an occlusion past the last step too) are
    warned about only once the command is going ahead: a refused one prints its error alone."""
    afile = tmp_path / "afile"
    afile.write_text("mine\n")
    extra = ["--out", str(afile)] if command == "run" else ["--set", "control.plan_over=belief"]
    scenario = "paper-fig3" if command == "run" else "swarm-3"
    r = _trackjam(command, scenario, "--set", "steps=3", "--set", "antenna.opening_angle_deg=1", *extra)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.splitlines()) == 1 and r.stderr.startswith("trackjam: error: "), r.stderr
    assert afile.read_text() == "mine\n"


def test_a_run_that_goes_ahead_still_warns(tmp_path):
    r = _trackjam("run", "paper-fig3", "--set", "steps=2", "--set", "filter.particles=500",
                  "--set", "filter.birth_particles=100", "--out", str(tmp_path / "run"), "--no-figures")
    assert r.returncode == 0, r.stderr
    assert ("trackjam: warning: target.occlusions: [14, 17] start after the last step (2), so this run has no "
            "such occlusion") in r.stderr.splitlines()


@pytest.mark.parametrize("name, figures", [("run.png", []), ("summary.json", ["--no-figures"]),
                                           ("steps.parquet", ["--no-figures"])])
def test_a_run_folder_whose_result_name_is_a_folder_is_refused_before_the_run(tmp_path, name, figures):
    # the run went ahead, rewrote the files before that one, then failed on it: a folder where a
    # file goes, in the folder of an earlier run of the same scenario
    out = tmp_path / "r"
    sets = ["--set", "steps=2", "--set", "filter.particles=100", "--set", "filter.birth_particles=20",
            "--set", "target.occlusions=[]"]
    assert _trackjam("run", "paper-fig3", *sets, "--no-figures", "--out", str(out)).returncode == 0
    (out / name).unlink(missing_ok=True)  # run.png: the first run wrote no figures
    (out / name).mkdir()
    (out / name / "mine").write_text("kept\n")
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    r = _trackjam("run", "paper-fig3", *sets, *figures, "--out", str(out))
    assert _one_line(r) == f"trackjam: error: --out {out}: {name} is a folder, not a file; move it away or choose another --out"
    assert "step" not in r.stdout  # refused before the warm-up and the run
    assert {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


@pytest.mark.parametrize(
    "args, line",
    [
        # the item was echoed as given: a newline split the one line in two, an escape sequence
        # reached the terminal (\x1b[2J clears it)
        (["validate", "paper-fig3", "--set", "name=a\nb"],
         "--set name=a\\nb: name: 'a b' is not a safe folder name: use 1 to 100 letters, digits, '_', '-', '+' or "
         "'.', starting with a letter or digit"),
        (["validate", "paper-fig3", "--set", "fil\nter.mode=1"],
         "--set fil\\nter.mode=1: fil\\nter: unknown key (did you mean filter?)"),
        (["validate", "paper-fig3", "--set", "steps=\x1b[2J"], "--set steps=\\x1b[2J: steps: must be an integer, got "
                                                               "str '\\x1b[2J'"),
        (["validate", "paper-fig3", "--set", "steps=[1,\n2"],
         "--set steps=[1,\\n2: not valid YAML: expected ',' or ']', but got '<stream end>' (line 2, column 2)"),
        (["validate", "a\nb.yaml"], "a\\nb.yaml: no such file (and no preset of that name; see `trackjam presets`)"),
    ],
)
def test_a_control_character_in_what_the_error_echoes_is_shown_escaped_on_the_one_line(tmp_path, args, line):
    r = _trackjam(*args, cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr == f"trackjam: error: {line}\n"


@pytest.mark.parametrize("value", ["abc", "0", "-2", "1e3", "99999999999999999999", "9" * 5000])
def test_a_bad_thread_count_in_the_environment_is_one_line(tmp_path, value):
    # TRACKJAM_THREADS (GRASP's threads when control.grasp.threads is null) went through int():
    # a ValueError traceback for "abc", and "99999999999999999999" asked for that many threads
    import os

    out = tmp_path / "r"
    r = subprocess.run([sys.executable, "-m", "trackjam", "run", "paper-fig3", "--set", "steps=2", "--set",
                        "filter.particles=100", "--set", "filter.birth_particles=20", "--no-figures", "--out", str(out)],
                       capture_output=True, text=True, env={**os.environ, "TRACKJAM_THREADS": value})
    assert _one_line(r) == (f"trackjam: error: TRACKJAM_THREADS={value if len(value) < 40 else value[:37] + '...'!r}: must be a whole number of threads in "
                            "[1, 1024] (or unset: one per agent up to the CPU count)")
    assert not out.exists()


def test_a_bad_thread_count_in_the_environment_is_refused_alone_before_the_warnings_and_the_kernels(tmp_path):
    # it was read while the kernels were loaded: after the scenario's warning (steps=2 ends before
    # paper-fig3's occlusion) and the "loading the compiled kernels" line, not as one line alone
    import os

    out = tmp_path / "r"
    r = subprocess.run([sys.executable, "-m", "trackjam", "run", "paper-fig3", "--set", "steps=2", "--no-figures",
                        "--out", str(out)], capture_output=True, text=True, env={**os.environ, "TRACKJAM_THREADS": "0"})
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == ("trackjam: error: TRACKJAM_THREADS='0': must be a whole number of threads in [1, 1024] "
                        "(or unset: one per agent up to the CPU count)\n")
    assert not out.exists()
    # a scenario that sets control.grasp.threads does not read it, and is refused all the same:
    # every command refuses a malformed environment, so that `validate` says what `run` would
    r = subprocess.run([sys.executable, "-m", "trackjam", "run", "paper-fig3", "--set", "steps=2", "--set",
                        "filter.particles=100", "--set", "filter.birth_particles=20", "--set", "control.grasp.threads=1",
                        "--no-figures", "--out", str(out)],
                       capture_output=True, text=True, env={**os.environ, "TRACKJAM_THREADS": "0"})
    assert _one_line(r).startswith("trackjam: error: TRACKJAM_THREADS='0': must be a whole number")
    assert not out.exists()


@pytest.mark.parametrize("variable", ["TRACKJAM_THREADS", "NUMBA_NUM_THREADS"])
@pytest.mark.parametrize("args", [["validate", "paper-fig3"], ["show-config", "paper-fig3"], ["presets"],
                                  ["bench", "--quick", "--only", "control"],
                                  ["experiment", "table1", "--trials", "1", "--steps", "1", "--workers", "1",
                                   "--out", "{tmp}/e"],
                                  ["run", "paper-fig3", "--set", "steps=1", "--out", "{tmp}/r"]])
@pytest.mark.parametrize("value", ["0", "-1", "abc"])
def test_every_command_refuses_a_bad_thread_count_in_the_environment(tmp_path, variable, args, value):
    # validate, experiment and bench took a TRACKJAM_THREADS that run refused (exit 0, no word);
    # NUMBA_NUM_THREADS=0 or -1 was a traceback from inside numba, "abc" a warning with one
    import os

    r = subprocess.run([sys.executable, "-m", "trackjam", *[a.format(tmp=tmp_path) for a in args]],
                       capture_output=True, text=True, env={**os.environ, variable: value})
    expected = {"TRACKJAM_THREADS": "in [1, 1024] (or unset: one per agent up to the CPU count)",
                "NUMBA_NUM_THREADS": ">= 1 (or unset: numba's default, the CPU count)"}[variable]
    assert _one_line(r) == f"trackjam: error: {variable}={value!r}: must be a whole number of threads {expected}"
    assert list(tmp_path.iterdir()) == []


def test_an_empty_numba_thread_count_is_refused_as_numba_reads_it_set():
    # numba counts NUMBA_NUM_THREADS= as set and printed a warning with a traceback
    import os

    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", "paper-fig3"], capture_output=True, text=True,
                       env={**os.environ, "NUMBA_NUM_THREADS": ""})
    assert _one_line(r).startswith("trackjam: error: NUMBA_NUM_THREADS='': must be a whole number of threads >= 1")


@pytest.mark.parametrize("variable, value", [("TRACKJAM_THREADS", "1"), ("TRACKJAM_THREADS", ""),
                                             ("NUMBA_NUM_THREADS", "1"), ("NUMBA_NUM_THREADS", "+2"),
                                             ("NUMBA_NUM_THREADS", "4096")])
def test_a_good_thread_count_in_the_environment_is_taken(variable, value):
    # numba takes what int() reads, with no bound of its own: a host of 4096 threads may say so
    import os

    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", "paper-fig3"], capture_output=True, text=True,
                       env={**os.environ, variable: value})
    assert r.returncode == 0 and r.stdout.startswith("ok"), r.stderr


@pytest.mark.parametrize("args", [["validate", "paper-fig3"], ["run", "paper-fig3", "--set", "steps=1", "--out", "{tmp}/r"]])
@pytest.mark.parametrize("variable, value, words", [
    ("NUMBA_OPT", "abc", "NUMBA_OPT='abc': numba cannot read this value"),
    ("NUMBA_DEVELOPER_MODE", "xyz", "NUMBA_DEVELOPER_MODE='xyz': numba cannot read this value"),
    ("NUMBA_DISABLE_JIT", "1", "NUMBA_DISABLE_JIT: trackjam's kernels must be compiled"),
])
def test_a_numba_variable_that_would_break_a_run_is_one_line(tmp_path, args, variable, value, words):
    # NUMBA_OPT=abc printed numba's warning of ten lines with a traceback and went on; with
    # NUMBA_DISABLE_JIT=1 validate said ok and run failed with a traceback of 160 lines
    import os

    r = subprocess.run([sys.executable, "-m", "trackjam", *[a.format(tmp=tmp_path) for a in args]],
                       capture_output=True, text=True, env={**os.environ, variable: value})
    assert _one_line(r).startswith(f"trackjam: error: {words}")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args", [["validate", "paper-fig3"], ["run", "paper-fig3", "--set", "steps=1", "--out", "{tmp}/r"]])
def test_a_matplotlib_backend_matplotlib_does_not_know_is_one_line_before_any_work(tmp_path, args):
    # MPLBACKEND=nonsense: validate said ok, run simulated every step, then failed with a
    # traceback where it imported matplotlib to draw its figure, and wrote nothing
    import os

    r = subprocess.run([sys.executable, "-m", "trackjam", *[a.format(tmp=tmp_path) for a in args]],
                       capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "nonsense"})
    assert _one_line(r).startswith("trackjam: error: MPLBACKEND='nonsense': matplotlib does not know this backend")
    assert list(tmp_path.iterdir()) == []


def test_the_backends_taken_without_loading_matplotlib_are_matplotlibs_own():
    import matplotlib.backends as backends  # a dependency of trackjam's, never skipped

    from trackjam.config.limits import MATPLOTLIB_BACKENDS

    assert MATPLOTLIB_BACKENDS == set(backends.backend_registry.list_builtin())


@pytest.mark.parametrize("variable, value", [("NUMBA_OPT", "2"), ("NUMBA_DISABLE_JIT", "0"), ("NUMBA_OPT", "max"),
                                             ("MPLBACKEND", "Agg"), ("MPLBACKEND", "svg")])
def test_a_numba_variable_numba_reads_is_taken(variable, value):
    import os

    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", "paper-fig3"], capture_output=True, text=True,
                       env={**os.environ, variable: value})
    assert r.returncode == 0 and r.stdout.startswith("ok") and r.stderr == "", r.stderr


@pytest.mark.parametrize("args", [["run", "paper-fig3", "--set", "steps=1", "--out", ""],
                                  ["experiment", "table1", "--trials", "1", "--steps", "1", "--out", ""],
                                  ["bench", "--quick", "--only", "control", "--json", ""]])
def test_an_empty_output_path_is_refused_not_read_as_the_current_folder(tmp_path, args):
    # Path("") is ".": `run --out ''` wrote the run's files into the current folder without a word
    line = _one_line(_trackjam(*args, cwd=tmp_path))
    option = args[-2]
    assert line.startswith(f"trackjam: error: {option} '': an empty path; name a ")
    assert list(tmp_path.iterdir()) == []


def test_a_run_and_an_experiment_write_into_a_folder_whose_name_is_not_utf8(tmp_path):
    # pyarrow refused such a path after the whole run: a traceback and a folder holding only
    # scenario.yaml; the Parquet files are now written through Python's own file objects
    import os

    def _trackjam(*args):  # the output echoes the path's bytes as they are
        return subprocess.run([sys.executable, "-m", "trackjam", *args], capture_output=True, text=True,
                              errors="surrogateescape")

    base = os.fsencode(tmp_path)
    run = os.fsdecode(base + b"/run\xff")
    r = _trackjam("run", "paper-fig3", "--set", "steps=2", "--set", "control.solver=exact", "--no-figures",
                  "--out", run)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert sorted(os.listdir(base + b"/run\xff")) == [b"agents.parquet", b"measurements.parquet", b"scenario.yaml",
                                                        b"steps.parquet", b"summary.json"]
    exp = os.fsdecode(base + b"/exp\xff")
    said = []
    for _ in range(2):  # the second reads the trials back
        r = _trackjam("experiment", "constraints", "--trials", "1", "--steps", "1", "--workers", "1", "--out", exp)
        assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
        said.append(r.stdout)
    assert "ran 2 trials; wrote" in said[0] and "all trials were already in OUT" in said[1]
    assert len(os.listdir(base + b"/exp\xff/trials")) == 2


def test_a_reader_that_stops_early_does_not_end_the_run(tmp_path):
    # `trackjam run ... | head -1`: the first progress line after head left raised BrokenPipeError,
    # exit 1 without a word, and no file was written
    out = tmp_path / "r"
    p = subprocess.Popen([sys.executable, "-m", "trackjam", "run", "paper-fig3", "--set", "steps=3", "--no-figures",
                          "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.readline()
    p.stdout.close()  # the reader is gone
    err = p.stderr.read().decode()
    assert p.wait() == 0 and "Traceback" not in err and "error" not in err, err
    assert sorted(f.name for f in out.iterdir()) == ["agents.parquet", "measurements.parquet", "scenario.yaml",
                                                     "steps.parquet", "summary.json"]


def test_a_listing_whose_reader_stops_early_ends_quietly():
    p = subprocess.Popen([sys.executable, "-m", "trackjam", "presets"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         bufsize=0)
    p.stdout.close()
    assert p.wait() == 0 and p.stderr.read() == b""


@pytest.mark.parametrize("shape", ["dangling", "loop", "dangling parent"])
@pytest.mark.parametrize("command", ["run", "experiment"])
def test_an_out_through_a_symbolic_link_that_leads_nowhere_is_refused_before_any_work(tmp_path, shape, command):
    """A dangling link (or a loop) where the output folder would be made: no folder can be made
    through it. `run` found that out only after the whole simulation (`cannot create the folder
    (File exists)`), `experiment` said "cannot write there (File exists)"."""
    link = tmp_path / "link"
    if shape == "loop":
        (tmp_path / "other").symlink_to(link)
        link.symlink_to(tmp_path / "other")
    else:
        link.symlink_to(tmp_path / "nowhere")
    out = link / "sub" if shape == "dangling parent" else link
    if command == "run":
        r = _trackjam("run", "paper-fig3", "--set", "steps=2", "--no-figures", "--out", str(out))
        assert "loading" not in r.stdout and "step" not in r.stdout  # refused before any work
    else:
        r = _trackjam("experiment", "table1", "--trials", "1", "--steps", "2", "--workers", "1", "--out", str(out))
    line = _one_line(r)
    assert line.startswith(f"trackjam: error: --out {out}: {link} is a symbolic link") and "leads nowhere" in line
    assert not (tmp_path / "nowhere").exists() and link.is_symlink()


def test_an_empty_scenario_name_a_device_as_out_and_a_typo_inside_a_target_list_are_named(tmp_path):
    """`validate ''` said ".: is a folder"; `--out /dev/null` was "a file"; a misspelt key of a
    target in `targets:` got no "did you mean"."""
    assert _one_line(_trackjam("validate", "")) == (
        "trackjam: error: '': an empty scenario name; give a preset (`trackjam presets`) or a YAML/TOML file")
    line = _one_line(_trackjam("run", "paper-fig3", "--out", "/dev/null", "--set", "steps=2"))
    assert line.endswith("--out /dev/null: is a device or a pipe, not a folder")
    f = tmp_path / "two.yaml"
    f.write_text("name: two\nsteps: 3\ntargets:\n  - {id: a, initial: [1, 1, 1, 0, 0, 0], apears: 1}\n"
                 "  - {id: b, initial: [5, 5, 5, 0, 0, 0]}\n")
    assert _one_line(_trackjam("validate", str(f))).endswith(
        "targets.0.apears: unknown key (did you mean targets.0.appears?)")


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP"])
def test_sigterm_or_sighup_ends_a_run_in_one_line_leaving_no_temporary_file(tmp_path, name):
    # SIGTERM ended it at once, status -15, with no word and sometimes a 0-byte
    # .steps.parquet.*.tmp.parquet; SIGHUP (a closed terminal, a dropped SSH session) at once,
    # status 129, its staging folder left behind: both now end it in one line, nothing left
    import signal

    out = tmp_path / "r"
    p = subprocess.Popen([sys.executable, "-m", "trackjam", "run", "paper-fig3", "--set", "control.solver=exact",
                          "--no-figures", "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in p.stdout:  # the run is under way (the loop ends, too, if the run ends first)
        if "step" in line:
            break
    p.send_signal(getattr(signal, name))
    _, err = p.communicate(timeout=120)
    assert p.returncode == 143, err
    assert err.splitlines()[-1] == "trackjam: terminated" and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.iterdir())  # stopped while stepping: nothing written


def test_an_error_a_ctrl_c_caused_is_said_as_a_ctrl_c(tmp_path):
    """A Ctrl-C while matplotlib's compiled module loads surfaces as "ImportError: initialization
    failed" chained from the KeyboardInterrupt: it was a traceback, then a fatal error at exit
    (status 134). It is the one line and status 130; the process ends at once."""
    code = textwrap.dedent(f"""
        import sys
        import trackjam.simulation.loop as loop
        def interrupted_import(*args, **kwargs):
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt as err:
                raise ImportError("initialization failed") from err
        loop.simulate = interrupted_import
        from trackjam.console import main
        sys.argv = ["trackjam", "run", "paper-fig3", "--set", "steps=2", "--set", "target.occlusions=[]",
                    "--out", {str(tmp_path / "r")!r}]
        main()
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 130, p.stderr
    assert p.stderr.strip().splitlines() == ["trackjam: interrupted"]
    assert not (tmp_path / "r").exists()


def test_a_sigterm_while_writing_removes_the_file_being_written(tmp_path):
    # SIGTERM is SystemExit(143) in the command: atomic_write removes its temporary file and keeps
    # the earlier file whole
    from trackjam.console import TERMINATED
    from trackjam.files import TEMP_MARK, atomic_write

    target = tmp_path / "steps.parquet"
    target.write_bytes(b"earlier")

    def write(tmp):
        tmp.write_bytes(b"half")
        raise SystemExit(TERMINATED)

    with pytest.raises(SystemExit):
        atomic_write(target, write)
    assert target.read_bytes() == b"earlier" and [f.name for f in tmp_path.iterdir()] == ["steps.parquet"]
    assert not any(TEMP_MARK in f.name for f in tmp_path.iterdir())


def test_a_ctrl_c_that_typer_caught_before_the_command_is_said(monkeypatch, capsys):
    # typer turns a KeyboardInterrupt before the command into exit status 130 without a word
    import typer.core

    from trackjam.cli import app

    def interrupt(self, ctx):
        raise KeyboardInterrupt

    monkeypatch.setattr(typer.core.TyperGroup, "invoke", interrupt)
    with pytest.raises(SystemExit) as err:
        app(["presets"])
    assert err.value.code == 130 and capsys.readouterr().err == "trackjam: interrupted\n"


def test_a_ctrl_c_while_the_command_line_loads_is_one_line(monkeypatch, capsys):
    # the console script imported typer and rich before any handler: a KeyboardInterrupt traceback
    import builtins

    import trackjam.console

    real = builtins.__import__

    def interrupted_import(name, *args, **kwargs):
        if name == "trackjam.cli":
            raise KeyboardInterrupt
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", interrupted_import)
    monkeypatch.setattr(trackjam.console.signal, "signal", lambda *args: None)  # not this process's SIGTERM
    with pytest.raises(SystemExit) as err:
        trackjam.console.main()
    assert err.value.code == 130 and capsys.readouterr().err == "trackjam: interrupted\n"


@pytest.mark.parametrize("signal_, code, how", [(KeyboardInterrupt, 130, "interrupted"), (SystemExit(143), 143, "terminated")])
def test_a_first_run_stopped_while_writing_leaves_no_folder_and_says_so_in_one_line(monkeypatch, tmp_path, capsys,
                                                                                   signal_, code, how):
    # each file was renamed into place as it was written: the folder was left without its summary.json
    import trackjam.viz.figure

    def stopped(*args, **kwargs):  # the run is stopped while its figure is drawn, after its tables
        raise signal_

    monkeypatch.setattr(trackjam.viz.figure, "plot_run", stopped)
    out = tmp_path / "r"
    with pytest.raises(SystemExit) as err:
        app(["run", "paper-fig3", "--set", "steps=1", "--set", "target.occlusions=[]", "--set", "control.solver=exact",
             "--out", str(out)])
    assert err.value.code == code
    assert capsys.readouterr().err == f"trackjam: {how} while writing {out}; nothing was written\n"
    assert list(tmp_path.iterdir()) == []


def test_a_run_stopped_before_its_folder_was_touched_says_nothing_was_written(monkeypatch, tmp_path, capsys):
    import trackjam.simulation.output as output

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(output, "write_run", interrupt)
    out = tmp_path / "r"
    with pytest.raises(SystemExit) as err:
        app(["run", "paper-fig3", "--set", "steps=1", "--set", "target.occlusions=[]", "--set", "control.solver=exact",
             "--out", str(out)])
    assert err.value.code == 130
    assert capsys.readouterr().err == f"trackjam: interrupted while writing {out}; nothing was written\n"


@pytest.mark.parametrize("env, redirect", [({}, "2>&1"), ({"PYTHONIOENCODING": "ascii"}, ""),
                                           ({"LC_ALL": "C", "PYTHONUTF8": "0"}, "")])
def test_a_reader_that_stops_early_does_not_end_the_run_whatever_the_encoding(tmp_path, env, redirect):
    # click wraps sys.stdout.buffer itself when the encoding is ASCII, past a guard on sys.stdout;
    # with 2>&1 the warnings on stderr met the closed pipe too
    import os

    out = tmp_path / "r"
    p = subprocess.Popen([sys.executable, "-m", "trackjam", "run", "paper-fig3", "--set", "steps=3", "--no-figures",
                          "--out", str(out)], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT if redirect else subprocess.PIPE, env={**os.environ, **env})
    p.stdout.readline()
    p.stdout.close()
    assert p.wait(timeout=300) == 0
    assert (out / "summary.json").exists()


@pytest.mark.parametrize("closed", [1, 2])
@pytest.mark.parametrize("args", [["--version"], ["presets"], ["validate", "paper-fig3"]])
def test_a_closed_standard_stream_is_the_null_device(args, closed):
    # `trackjam --version >&-` was a traceback, and with `2>&-` a command that did its work
    # ended with exit status 1
    r = subprocess.run([sys.executable, "-m", "trackjam", *args], capture_output=True, text=True,
                       preexec_fn=lambda: os.close(closed))
    assert r.returncode == 0
    assert "Traceback" not in r.stdout + r.stderr


def test_a_run_with_both_standard_streams_closed_writes_its_files(tmp_path):
    out = tmp_path / "r"

    def close_both():
        os.close(1)
        os.close(2)

    r = subprocess.run([sys.executable, "-m", "trackjam", "run", "paper-fig3", "--set", "steps=2", "--no-figures",
                        "--out", str(out)], preexec_fn=close_both)
    assert r.returncode == 0
    assert sorted(f.name for f in out.iterdir()) == ["agents.parquet", "measurements.parquet", "scenario.yaml",
                                                     "steps.parquet", "summary.json"]
    bad = subprocess.run([sys.executable, "-m", "trackjam", "validate", "no-such-preset"], preexec_fn=close_both)
    assert bad.returncode == 2  # the one line went nowhere, the status still says it


def test_an_ascii_output_gets_the_experiments_table_in_ascii(tmp_path):
    # LC_ALL=C with PYTHONUTF8=0 (or PYTHONIOENCODING=ascii): the closing table's "±" ended the
    # experiment in a UnicodeEncodeError traceback, exit status 1, after its files were written
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONUTF8", "LC_ALL", "LANG")}
    env |= {"PYTHONIOENCODING": "ascii", "LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    r = subprocess.run([sys.executable, "-m", "trackjam", "experiment", "constraints", "--trials", "2", "--steps", "2",
                        "--workers", "1", "--out", str(tmp_path / "e")], capture_output=True, env=env)
    assert r.returncode == 0 and b"Traceback" not in r.stderr, r.stderr.decode(errors="replace")
    assert b"mean +- 95% CI" in r.stdout and b" +- " in r.stdout
    assert r.stdout.isascii()


def test_a_team_that_never_transmits_is_warned_about(tmp_path):
    # at a 60 dBW top level no plan is worth more than silence, and the antennas stay off
    # for the whole run: the table showed held steps (the cue's estimate, coasted) without a word
    r = _trackjam("run", "paper-fig3", "--set", "antenna.power_levels_db=[off, 60]", "--set", "steps=2",
                  "--no-figures", "--out", str(tmp_path / "r"))
    assert r.returncode == 0, r.stderr
    assert "trackjam: warning: the team never transmitted (mean transmit power 0 W)" in r.stderr
    ok = _trackjam("run", "paper-fig3", "--set", "steps=2", "--no-figures", "--out", str(tmp_path / "ok"))
    assert ok.returncode == 0 and "never transmitted" not in ok.stderr


@pytest.mark.parametrize("where", ["simulate", "plot_run"])
def test_an_error_a_sigterm_caused_is_said_as_a_sigterm(tmp_path, where):
    """A SIGTERM (or SIGHUP) while a compiled module of matplotlib loads surfaces as "ImportError:
    initialization failed" chained from the handler's SystemExit(143), as a Ctrl-C there does from
    its KeyboardInterrupt: `kill -HUP` at the start of a run's writing was a traceback of 60 lines
    and exit status 1. It is the one line and status 143, whether it came while stepping or while
    writing (an earlier run in the folder kept whole)."""
    out = tmp_path / "r"
    target = "trackjam.simulation.loop.simulate" if where == "simulate" else "trackjam.viz.figure.plot_run"
    module, name = target.rsplit(".", 1)
    code = textwrap.dedent(f"""
        import sys, importlib
        def terminated_import(*args, **kwargs):
            try:
                raise SystemExit(143)
            except SystemExit as err:
                raise ImportError("initialization failed") from err
        setattr(importlib.import_module({module!r}), {name!r}, terminated_import)
        from trackjam.console import main
        sys.argv = ["trackjam", "run", "paper-fig3", "--set", "steps=1", "--set", "target.occlusions=[]",
                    "--set", "control.solver=exact", "--out", {str(out)!r}]
        main()
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 143, p.stderr
    said = "trackjam: terminated" if where == "simulate" else f"trackjam: terminated while writing {out}; nothing was written"
    assert p.stderr.strip().splitlines() == [said]
    assert not out.exists()



@pytest.mark.parametrize("where", ["run", "experiment", "import"])
def test_a_ctrl_c_inside_code_a_library_runs_with_exec_is_exit_130_not_a_death_by_sigint(tmp_path, where):
    """A Ctrl-C that lands in code run by exec() or eval() of a text (a dataclass's __init__, a
    namedtuple, as a module loads) makes Python note an unhandled KeyboardInterrupt, which
    `python -m` kept even once the command had caught it and said `trackjam: interrupted`: the
    process then killed itself with SIGINT at its very end (status -2, not 130): 2 of 94 Ctrl-Cs
    sent 0 to 1 s after a short sweep's last trial, while the figure's modules loaded. It is the one line
    and status 130, whether it lands while running, while writing an experiment's results, or
    while the command line loads."""
    out = tmp_path / "out"
    patch = {
        "run": ("trackjam.simulation.loop", "simulate", ["run", "paper-fig3", "--set", "steps=1", "--no-figures"]),
        "experiment": ("trackjam.experiments.engine", "_finish",
                       ["experiment", "constraints", "--trials", "1", "--steps", "1", "--workers", "1"]),
    }
    if where == "import":  # the Ctrl-C while typer loads, under the entry point's own handler
        setup = ("import builtins\nreal = builtins.__import__\n"
                 "def hit(name, *a, **k):\n"
                 "    if name == 'typer':\n"
                 "        exec('raise KeyboardInterrupt')\n"
                 "    return real(name, *a, **k)\n"
                 "builtins.__import__ = hit\n")
        argv = ["run"]
    else:
        module, name, argv = patch[where]
        setup = (f"import importlib\nm = importlib.import_module({module!r})\n"
                 "def hit(*a, **k):\n"
                 "    exec('raise KeyboardInterrupt')\n"
                 f"m.{name} = hit\n")
        argv = [*argv, "--out", str(out)]
    # run as `python -m`, as `python -m trackjam` runs: a script or -c exits past the note
    (tmp_path / "ctrl_c_in_exec.py").write_text(
        setup + f"import sys\nsys.argv = ['trackjam', *{argv!r}]\nfrom trackjam.console import main\nmain()\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    p = subprocess.run([sys.executable, "-m", "ctrl_c_in_exec"], capture_output=True, text=True, timeout=300, env=env)
    assert p.returncode == 130, (p.returncode, p.stderr[-2000:])
    assert p.stderr.strip().splitlines()[-1] == "trackjam: interrupted" and "Traceback" not in p.stderr


def test_a_ctrl_c_as_a_finished_command_ends_keeps_its_status(tmp_path):
    """A Ctrl-C while the entry point flushes the output of a command that has finished (after
    its files are written) leaves the command's exit status, without a traceback: it was a
    KeyboardInterrupt traceback and death by SIGINT."""
    (tmp_path / "ctrl_c_at_the_end.py").write_text(
        "import sys\nimport trackjam.console as console\nreal, calls = console._drain, []\n"
        "def drain(stream):\n"
        "    calls.append(stream)\n"
        "    if len(calls) == 1:\n"
        "        raise KeyboardInterrupt\n"
        "    real(stream)\n"
        "console._drain = drain\nsys.argv = ['trackjam', 'presets']\nconsole.main()\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    p = subprocess.run([sys.executable, "-m", "ctrl_c_at_the_end"], capture_output=True, text=True, timeout=120, env=env)
    assert p.returncode == 0 and p.stderr == "", (p.returncode, p.stderr[-2000:])
    assert "paper-fig3" in p.stdout


def test_a_ctrl_c_a_compiled_module_swallowed_is_said_as_a_ctrl_c(tmp_path):
    """A Ctrl-C whose KeyboardInterrupt a compiled module swallowed, failing in its own words
    instead (matplotlib's `affine_transform` as a sweep drew its figure: "TypeError: incompatible
    function arguments", a traceback and exit status 1), is the Ctrl-C's one line and status 130;
    without a Ctrl-C the same error is a traceback, as before."""
    hit = ("import os, signal, time, importlib\n"
           "m = importlib.import_module('trackjam.experiments.engine')\n"
           "def swallowed(*a, **k):\n"
           "    try:\n"
           "        if CTRL_C:\n"
           "            os.kill(os.getpid(), signal.SIGINT)\n"
           "            time.sleep(5)\n"
           "    except KeyboardInterrupt:\n"
           "        pass\n"
           "    raise TypeError('affine_transform(): incompatible function arguments')\n"
           "m._finish = swallowed\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    for ctrl_c in (True, False):
        out = tmp_path / f"out{ctrl_c}"
        argv = ["experiment", "constraints", "--trials", "1", "--steps", "1", "--workers", "1", "--out", str(out)]
        (tmp_path / "swallowed_ctrl_c.py").write_text(
            f"CTRL_C = {ctrl_c}\n" + hit +
            f"import sys\nsys.argv = ['trackjam', *{argv!r}]\nfrom trackjam.console import main\nmain()\n")
        p = subprocess.run([sys.executable, "-m", "swallowed_ctrl_c"], capture_output=True, text=True, timeout=300,
                           env=env)
        if ctrl_c:
            assert p.returncode == 130, (p.returncode, p.stderr[-2000:])
            assert p.stderr.strip().splitlines()[-1] == "trackjam: interrupted" and "Traceback" not in p.stderr
        else:
            assert p.returncode == 1 and "incompatible function arguments" in p.stderr, p.stderr[-2000:]
        assert (out / "trials" / "c01-t0000.parquet").is_file()  # the trials written stay
