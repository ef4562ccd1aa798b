"""The command line: presets, show-config, validate, and bad input (one line, exit 2)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from readme_tables import closing_table_rows
from trackjam.cli import app

runner = CliRunner()


def test_presets_lists_paper_fig3():
    r = runner.invoke(app, ["presets"])
    assert r.exit_code == 0 and "paper-fig3" in r.output


def test_show_config_prints_the_resolved_scenario_with_overrides():
    r = runner.invoke(app, ["show-config", "paper-fig3", "--set", "antenna.opening_angle_deg=120"])
    assert r.exit_code == 0
    data = yaml.safe_load(r.output)
    assert data["antenna"]["opening_angle_deg"] == 120 and data["control"]["grasp"]["samples"] == 10000


def test_validate_accepts_a_good_file(tmp_path):
    f = tmp_path / "ok.yaml"
    f.write_text("name: ok\nsteps: 4\n")
    r = runner.invoke(app, ["validate", str(f)])
    assert r.exit_code == 0 and "ok" in r.output


@pytest.mark.parametrize(
    "text, key",
    [
        ("antena: {height: 3}\n", "antena"),
        ("steps: many\n", "steps"),
        ("antenna: {height: -40}\n", "antenna.height"),
        ("antenna: {opening_angle_deg: 190}\n", "antenna.opening_angle_deg"),
        ("antenna: {power_levels_db: []}\n", "antenna.power_levels_db"),
        ("antenna: {r0: .nan}\n", "antenna.r0"),
        ("steps: [\n", "YAML"),
    ],
)
def test_bad_files_exit_2_with_one_line(tmp_path, text, key):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", str(f)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and key in lines[0]


def test_missing_file_exits_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", str(tmp_path / "nope.yaml")], capture_output=True, text=True)
    assert r.returncode == 2 and "no such file" in r.stderr and "Traceback" not in r.stderr


def test_bad_set_exits_2():
    r = runner.invoke(app, ["show-config", "paper-fig3", "--set", "antenna.height"])
    assert r.exit_code == 2


def trackjam(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "trackjam", *args], capture_output=True, text=True, cwd=cwd)


def one_line_exit_2(r, *words):
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr and "Traceback" not in r.stdout
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("trackjam: error: ")
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize(
    "item, key",
    [
        ("antenna.power_levels_db=[off, 5000]", "antenna.power_levels_db"),
        ("area.high=[1e300, 1e300, 1e300]", "area.high"),
        ("agents.n_inclination=1000", "agents.n_inclination"),
        ("control.grasp.samples=1e9", "control.grasp.samples"),
        ("steps=true", "steps"),
    ],
)
def test_validate_refuses_values_past_their_bounds_in_one_line(item, key):
    one_line_exit_2(trackjam("validate", "paper-fig3", "--set", item), f"--set {item}: {key}")


def write_bytes(tmp_path, name, data):
    f = tmp_path / name
    f.write_bytes(data)
    return str(f)


@pytest.mark.parametrize(
    "name, data, words",
    [
        ("empty.yaml", b"", ["is empty"]),
        ("comments.yaml", b"# only a comment\n", ["is empty"]),
        ("utf16.yaml", "steps: 3\n".encode("utf-16"), ["not UTF-8 text", "UTF-16"]),
        ("binary.yaml", bytes(range(256)) * 4, ["not UTF-8 text"]),
        ("nul.yaml", b"steps: 3\n\x00\x00", ["NUL"]),
        ("dup.yaml", b"steps: 3\nantenna: {height: 3}\nsteps: 4\n", ["duplicate key 'steps' (line 3)"]),
        ("dup2.yaml", b"antenna:\n  height: 3\n  r0: 1\n  height: 4\n", ["duplicate key 'height' (line 4)"]),
        ("big.yaml", b"#" * 2_000_000, ["larger than 1 MB"]),
        ("typo.yaml", b"antenna: {heigth: 3}\n", ["antenna.heigth: unknown key (did you mean antenna.height?)"]),
        ("typo2.yaml", b"filtr: {particles: 30}\n", ["filtr: unknown key (did you mean filter?)"]),
        ("far.yaml", b"xyz: 1\n", ["xyz: unknown key"]),
        ("list.yaml", b"- 1\n- 2\n", ["must be a mapping"]),
        ("big.toml", b"steps = 3\nsteps = 4\n", ["not valid TOML"]),
    ],
)
def test_bad_scenario_files_are_one_line(tmp_path, name, data, words):
    path = write_bytes(tmp_path, name, data)
    line = one_line_exit_2(trackjam("validate", path), path, *words)
    if name == "far.yaml":
        assert "did you mean" not in line


@pytest.mark.parametrize("device, words", [("/dev/null", "is empty"), ("/dev/zero", "larger than 1 MB")])
def test_devices_are_refused_and_never_read_forever(device, words):
    one_line_exit_2(trackjam("validate", device), words)


def test_a_float_written_with_an_exponent_is_a_number_in_yaml(tmp_path):
    from trackjam.config import load_scenario

    path = write_bytes(tmp_path, "e.yaml", b"filter: {particles: 2e3, birth_speed: 1e300}\n")
    one_line_exit_2(trackjam("validate", path), "filter.birth_speed: Input should be less than or equal to 1000")
    path = write_bytes(tmp_path, "f.yaml", b"filter: {particles: 2e3, birth_speed: 1.5e0}\n")
    s = load_scenario(path)
    assert s.filter.particles == 2000 and s.filter.birth_speed == 1.5


def test_a_set_error_is_blamed_on_the_set_and_a_file_error_on_the_file(tmp_path):
    path = write_bytes(tmp_path, "s.yaml", b"antenna: {heigth: 3}\n")
    line = one_line_exit_2(trackjam("validate", path, "--set", "antenna.r0=-1"))
    assert line.index("--set antenna.r0=-1: antenna.r0:") < line.index(f"{path}: antenna.heigth")
    path = write_bytes(tmp_path, "t.yaml", b"steps: 5\n")
    one_line_exit_2(trackjam("validate", path, "--set", "control.at_least=9"), "--set control.at_least=9: control.at_least (9)")


@pytest.mark.parametrize(
    "args, words",
    [
        (["run", "--seed", "abc"], ["--seed"]),
        (["run", "--bogus"], ["--bogus"]),
        (["nosuch"], ["nosuch"]),
        (["experiment", "table1", "--trials", "x"], ["--trials"]),
    ],
)
def test_malformed_options_are_one_line_not_a_box(args, words):
    one_line_exit_2(trackjam(*args), *words)


def test_version():
    import trackjam as tj

    r = trackjam("--version")
    assert r.returncode == 0 and r.stdout.strip() == f"trackjam {tj.__version__}"


def test_suspicious_values_warn_one_line_each_and_validate_still_says_ok():
    r = trackjam(
        "validate", "paper-fig3",
        "--set", "antenna.opening_angle_deg=1.4",
        "--set", "target.appears=31",
        "--set", "target.occlusions=[[14, 17], [29, 40]]",
        "--set", "agents.initial=[[5, 5, 5], [7, 7, 7], [5, 5, 5], [5, 5, 5]]",
    )
    assert r.returncode == 0 and r.stdout.startswith("ok"), r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 4 and all(l.startswith("trackjam: warning: ") for l in lines)
    assert "antenna.opening_angle_deg" in lines[0] and "radians by mistake" in lines[0] and "80 deg" in lines[0]
    assert "target.appears" in lines[1] and "after the last step (30)" in lines[1]
    assert "target.occlusions: [29, 40]" in lines[2] and "[14, 17]" not in lines[2]
    assert "agents.initial: [0], [2], [3]" in lines[3]


def test_a_delay_that_outlasts_the_run_is_warned_about():
    r = trackjam("validate", "paper-fig3", "--set", "comms.delay_steps=30")
    assert r.returncode == 0 and r.stdout.startswith("ok"), r.stderr
    assert r.stderr.splitlines() == ["trackjam: warning: comms.delay_steps: 30 is not less than steps (30); no "
                                     "teammate's message ever arrives, and each agent acts alone on its own filter"]
    assert trackjam("validate", "paper-fig3", "--set", "comms.delay_steps=29").stderr == ""


def test_an_ordinary_scenario_gives_no_warning():
    r = trackjam("validate", "paper-fig3")
    assert r.returncode == 0 and r.stderr == ""


def test_a_named_pipe_is_refused_without_waiting_for_a_writer(tmp_path):
    import os

    fifo = tmp_path / "scenario.yaml"
    os.mkfifo(fifo)
    r = subprocess.run([sys.executable, "-m", "trackjam", "validate", str(fifo)], capture_output=True, text=True, timeout=60)
    one_line_exit_2(r, "is a pipe or a socket")


def test_an_abort_outside_a_command_is_one_line_and_exit_130(monkeypatch, capsys):
    import typer

    from trackjam import cli

    def abort(*args, **kwargs):
        raise typer.Abort()

    monkeypatch.setattr(typer.Typer, "__call__", abort)
    with pytest.raises(SystemExit) as exit_:
        cli.app()
    assert exit_.value.code == 130
    assert capsys.readouterr().err.strip() == "trackjam: interrupted"


def test_a_run_with_several_targets_runs_on_the_swarm_engine_and_writes_its_logs(tmp_path):
    """`targets:` with K > 1 runs end to end: the swarm's closing table per target and its five
    logs; an option the swarm engine does not simulate is one line naming the key, exit 2,
    nothing written."""
    f = tmp_path / "two.yaml"
    f.write_text("targets:\n  - {id: a}\n  - {id: b, initial: [60, 60, 60, -1, 0, 0]}\nsteps: 2\n"
                 "filter: {particles: 200, birth_particles: 50}\n")
    assert runner.invoke(app, ["validate", str(f)]).exit_code == 0
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "trackjam", "run", str(f), "--out", str(out), "--no-figures"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "target a: held" in r.stdout and "target b: held" in r.stdout and "2 targets" in r.stdout
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["scenario.yaml", "summary.json", "steps.parquet", "targets.parquet", "tracks.parquet", "agents.parquet",
         "measurements.parquet"])
    assert json.loads((out / "summary.json").read_text())["ids"] == ["a", "b"]
    bad = tmp_path / "bad"
    r = subprocess.run([sys.executable, "-m", "trackjam", "run", str(f), "--out", str(bad), "--set",
                        "fusion.existence=evidence"], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.startswith("trackjam: error: --set fusion.existence=evidence: fusion.existence:")
    assert not bad.exists()


def test_the_readmes_quick_start_table_is_what_the_run_prints(tmp_path):
    """The closing table the README shows for `trackjam run paper-fig3` (seed 1) is the one the run
    prints today, row by row (the time per step, left out there, aside): a change to the filter
    or the solver that moves the run makes this fail until the README is redone."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    block = readme.split("The closing table of that run", 1)[1].split("```", 2)[1]
    shown = closing_table_rows(block)
    assert len(shown) >= 10 and "jamming incidents per agent" in shown
    r = runner.invoke(app, ["run", "paper-fig3", "--out", str(tmp_path / "run"), "--no-figures"])
    assert r.exit_code == 0, r.output
    printed = closing_table_rows(r.output)
    assert {k: printed.get(k) for k in shown} == shown


def test_the_ospa_row_names_the_scenarios_own_order_and_cut_off(tmp_path):
    """The closing table's OSPA label says the p and c the run used, not the defaults."""
    r = runner.invoke(app, ["run", "paper-fig3", "--out", str(tmp_path / "run"), "--no-figures", "--set", "steps=2",
                            "--set", "metrics.ospa_cutoff=5", "--set", "metrics.ospa_order=1"])
    assert r.exit_code == 0, r.output
    assert "mean OSPA (p=1, c=5) [m]" in r.output and "c=10" not in r.output


def _help(*args: str) -> str:
    r = runner.invoke(app, [*args, "--help"])
    assert r.exit_code == 0, r.output
    return r.output


@pytest.mark.parametrize(
    "args, flags",
    [((), ["--version", "--help"]), (("run",), ["--figures", "--help"]), (("bench",), ["--quick", "--help"])],
)
def test_help_shows_no_value_beside_a_flag(args, flags):
    out = _help(*args)
    assert "<bool>" not in out
    for flag in flags:
        line = next(ln for ln in out.splitlines() if f" {flag} " in ln)
        assert "<" not in line, line
    if args:  # an option that takes a value still shows its type
        assert "<path>" in out


def test_experiment_help_lists_every_scheduler_scheme():
    words = " ".join(_help("experiment").replace("│", " ").split())
    assert "[SCHEME://]HOST:PORT with tcp (the default), tls, ws or wss" in words


@pytest.mark.parametrize("typo, preset", [("paper_fig3", "paper-fig3"), ("swarm3", "swarm-3"), ("Paper-Fig3", "paper-fig3")])
def test_a_misspelt_preset_gets_a_did_you_mean(typo, preset, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(app, ["validate", typo])
    assert r.exit_code == 2
    assert r.output == f"trackjam: error: {typo}: no such file (and no preset of that name; did you mean {preset}?)\n"


def test_a_name_far_from_every_preset_points_to_the_list(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(app, ["validate", "nothing-like-it"])
    assert r.exit_code == 2 and "did you mean" not in r.output and "see `trackjam presets`" in r.output


@pytest.mark.parametrize("name", ["table1", "swarm"])
def test_an_experiments_bad_set_is_named_as_run_names_it(name, tmp_path):
    # it said "base scenario of the experiment (preset paper-fig3 with --set): antena: ..."
    r = runner.invoke(app, ["experiment", name, "--set", "antena.pointing=aim", "--out", str(tmp_path / "e")])
    assert r.exit_code == 2
    line = "--set antena.pointing=aim: antena: unknown key (did you mean antenna?)"
    assert r.output == f"trackjam: error: {line}\n"
    assert runner.invoke(app, ["run", "--set", "antena.pointing=aim"]).output == r.output
    assert not (tmp_path / "e").exists()


def test_an_option_the_swarm_engine_does_not_simulate_is_blamed_on_its_set(tmp_path):
    problem = "control.plan_over: 'belief' is not simulated with several targets yet; the swarm engine runs with 'point'"
    for command in ("validate", "run"):
        r = runner.invoke(app, [command, "swarm-3", "--set", "control.plan_over=belief", "--set", "steps=2"])
        assert r.exit_code == 2 and r.output == f"trackjam: error: --set control.plan_over=belief: {problem}\n"
    # set by a file, it is the file's (the message names its key, as before)
    from trackjam.config import load_scenario, scenario_to_yaml

    f = tmp_path / "belief.yaml"
    f.write_text(scenario_to_yaml(load_scenario("swarm-3", ["control.plan_over=belief"])))
    r = runner.invoke(app, ["validate", str(f), "--set", "steps=2"])
    assert r.exit_code == 2 and r.output == f"trackjam: error: {problem}\n"


@pytest.mark.parametrize("occlusions, words", [
    ("[]", "no hidden spell between detectable steps"),
    ("[[1, 30]]", "no detectable step"),  # it had said "no undetectable spell" of a target hidden throughout
    ("[[25, 30]]", "no hidden spell between detectable steps"),  # hidden at the end: not a spell to re-acquire after
])
def test_the_re_acquisition_row_says_why_there_is_nothing_to_show(tmp_path, occlusions, words):
    r = CliRunner().invoke(app, ["run", "paper-fig3", "--out", str(tmp_path / "r"), "--set", "steps=30",
                                 "--set", f"target.occlusions={occlusions}", "--set", "filter.particles=300",
                                 "--set", "filter.birth_particles=60", "--no-figures"])
    assert r.exit_code == 0, r.output
    row = next(line for line in r.output.splitlines() if "re-acquired after each hidden spell" in line)
    assert words in row


LITERAL_WARNING = "leaves out filter.cue, fusion.existence and control.fallback"


def test_a_file_that_leaves_out_the_three_practical_choices_is_warned_about_once(tmp_path):
    f = tmp_path / "small.yaml"
    f.write_text("name: small\nsteps: 12\nantenna:\n  opening_angle_deg: 100\n")
    r = trackjam("validate", str(f))
    assert r.returncode == 0 and r.stdout.startswith("ok: small"), r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"trackjam: warning: {f}: {LITERAL_WARNING}")
    assert "base: paper-fig3" in lines[0]


@pytest.mark.parametrize("text, sets", [
    ("base: paper-fig3-literal\nsteps: 12\n", []),  # a base says what the file starts from
    ("steps: 12\nfusion: {existence: mean}\n", []),  # naming a choice, even at its literal value
    ("steps: 12\ncontrol:\n  fallback: hover\n", []),
    ("steps: 12\n", ["--set", "filter.cue.existence=0.5"]),
    ("steps: 12\n", ["--set", "control.fallback=hover"]),
])
def test_a_file_that_names_a_practical_choice_or_a_base_is_not_warned_about(tmp_path, text, sets):
    f = tmp_path / "s.yaml"
    f.write_text(text)
    r = trackjam("validate", str(f), *sets)
    assert r.returncode == 0 and LITERAL_WARNING not in r.stderr, r.stderr


def test_presets_says_what_each_preset_is_for():
    from trackjam.config import preset_names
    from trackjam.config.loading import PRESET_SUMMARIES

    r = runner.invoke(app, ["presets"])
    lines = r.output.splitlines()
    assert r.exit_code == 0 and len(lines) == len(preset_names()) == len(PRESET_SUMMARIES)
    for name, line in zip(preset_names(), lines):
        assert line.startswith(name + " ") and line.endswith(": " + PRESET_SUMMARIES[name])
    assert len(set(PRESET_SUMMARIES.values())) == len(PRESET_SUMMARIES)  # paper-fig3 and -literal told apart


def test_a_preset_dropped_into_the_folder_is_summed_up_by_its_first_comment(monkeypatch):
    from trackjam.config import loading

    monkeypatch.delitem(loading.PRESET_SUMMARIES, "pursuit")
    assert loading.preset_summary("pursuit").startswith("The recommended preset for holding a target")


@pytest.mark.parametrize("text, words", [
    ("antenna:\nheight: 30\n", "antenna: a section, given no value (are its keys indented under it? leave the "
                               "section out for its defaults); height: unknown key"),
    ("antenna: 3\n", "antenna: a section of keys (key: value, indented under it), got the number 3"),
    ("antenna: hello\n", "antenna: a section of keys (key: value, indented under it), got the text 'hello'"),
    ("control: {grasp: [1, 2]}\n", "control.grasp: a section of keys (key: value, indented under it), got a list"),
])
def test_a_section_that_is_not_a_mapping_says_so_in_words(tmp_path, text, words):
    f = tmp_path / "s.yaml"
    f.write_text(text)
    one_line_exit_2(trackjam("validate", str(f)), f"{f}: {words}")


@pytest.mark.parametrize("item, hint", [
    ("control.solver=Exact", "(did you mean exact?)"),
    ("control.solver=grsp", "(did you mean grasp?)"),
    ("antenna.pointing=AIM", "(did you mean aim?)"),
    ("fusion.share=scan", "(did you mean scans?)"),
])
def test_a_misspelt_choice_gets_a_did_you_mean(item, hint):
    r = trackjam("validate", "paper-fig3", "--set", item)
    one_line_exit_2(r, f"--set {item}: ")
    assert r.stderr.strip().endswith(hint)
    assert "did you mean" not in trackjam("validate", "paper-fig3", "--set", "control.solver=xyz").stderr


def test_a_misspelt_experiment_gets_a_did_you_mean():
    one_line_exit_2(trackjam("experiment", "tabel1"), "unknown experiment 'tabel1' (did you mean table1?); choose one of")


def test_show_config_refuses_what_validate_refuses_for_the_swarm_engine():
    v = trackjam("validate", "swarm-3", "--set", "control.plan_over=belief")
    s = trackjam("show-config", "swarm-3", "--set", "control.plan_over=belief")
    assert one_line_exit_2(s, "--set control.plan_over=belief") == one_line_exit_2(v, "--set control.plan_over=belief")
    assert s.stdout == ""


def test_a_file_of_several_targets_is_pointed_to_a_base_it_can_run_on(tmp_path):
    """The swarm engine runs with fusion.existence: mean only: the warning said the file 'leaves
    out' it and pointed to `base: paper-fig3`, on which the same file is refused
    (fusion.existence: 'evidence' is not simulated with several targets)."""
    targets = "targets:\n  - {id: a, initial: [20, 20, 20, 1, 1, 1]}\n  - {id: b, initial: [60, 60, 60, 0, 0, 0]}\n"
    f = tmp_path / "two.yaml"
    f.write_text(targets)
    r = trackjam("validate", str(f))
    assert r.returncode == 0, r.stderr
    (line,) = r.stderr.splitlines()
    assert "leaves out filter.cue and control.fallback" in line and "fusion.existence" not in line
    base = line.split("`base: ", 1)[1].split("`", 1)[0]
    g = tmp_path / "based.yaml"
    g.write_text(f"base: {base}\n{targets}")
    r = trackjam("validate", str(g))
    assert r.returncode == 0 and r.stderr == "", r.stderr


def test_the_experiment_commands_help_names_every_experiment():
    """`trackjam experiment --help` lists the experiments by a hand-written text (cli.py loads no
    experiment to draw its help): an experiment added to EXPERIMENTS must be named there too."""
    import typer.main

    from trackjam.experiments.definitions import EXPERIMENTS

    command = typer.main.get_command(app).commands["experiment"]
    name = next(p for p in command.params if p.name == "name")
    assert name.help.split(" | ") == list(EXPERIMENTS)
