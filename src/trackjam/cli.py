"""The `trackjam` command line. Heavy imports live inside the commands so `--help` is fast.

A mistake of the user's (bad key, bad value, missing file, unusable --out) is one line on
stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import errno
import functools
import sys
from pathlib import Path
from typing import Callable, NoReturn, Optional

import typer
from typer.core import TyperCommand, TyperGroup

from trackjam.console import TERMINATED  # the exit status of a command ended by SIGTERM
from trackjam.errors import counted


def _flags_take_no_value(cls: type) -> type:
    """``cls`` (a typer command or group) whose help shows no type beside a flag: typer printed
    ``--quick <bool>``, ``--figures --no-figures <bool>``, as if the flag took a value."""

    class Command(cls):
        def format_help(self, ctx, formatter):
            for param in self.get_params(ctx):
                if getattr(param, "is_flag", False) and param.metavar is None:
                    param.metavar = ""  # what typer shows in the type's place
            return super().format_help(ctx, formatter)

    Command.__name__ = Command.__qualname__ = f"_{cls.__name__}"
    return Command


_Command = _flags_take_no_value(TyperCommand)


class _Cli(typer.Typer):
    """Typer whose usage errors (``--seed abc``, an unknown option) are one line and exit 2 too,
    instead of a framed multi-line box."""

    def __call__(self, *args, **kwargs):
        if "standalone_mode" in kwargs:
            return super().__call__(*args, **kwargs)
        global _said_interrupted, _said_terminated
        _said_interrupted = _said_terminated = False
        # typer may vendor its own click: take the exceptions from where its BadParameter lives
        click_errors = sys.modules[typer.BadParameter.__module__]
        try:
            rv = super().__call__(*args, standalone_mode=False, **kwargs)
        except click_errors.NoArgsIsHelpError as err:  # plain `trackjam`: the help, as click shows it
            err.show()
            sys.exit(err.exit_code)
        except click_errors.ClickException as err:
            typer.echo(f"trackjam: error: {' '.join(err.format_message().split())}", err=True)
            sys.exit(err.exit_code)
        except (typer.Abort, KeyboardInterrupt, SystemError) as err:
            if isinstance(err, SystemError) and not interrupted(err):
                raise
            typer.echo("trackjam: interrupted", err=True)
            sys.exit(130)
        except OSError as err:
            # the help or the version (written before any command runs, so outside user_errors)
            # on a full disk (`--help > /dev/full`): the same line as a command's output there
            if err.filename is None and _full_disk(err):
                typer.echo(f"trackjam: error: {_full_disk(err)}", err=True)
                sys.exit(2)
            raise
        if rv == 130 and not _said_interrupted:  # typer's own Exit(130) for a Ctrl-C before the command ran
            typer.echo("trackjam: interrupted", err=True)
        sys.exit(rv if isinstance(rv, int) else 0)

    def command(self, *args, **kwargs):
        kwargs.setdefault("cls", _Command)
        return super().command(*args, **kwargs)


app = _Cli(
    cls=_flags_take_no_value(TyperGroup),
    add_completion=False,
    no_args_is_help=True,
    help="Cooperative tracking and radio-jamming of a rogue drone by a team of pursuer drones.",
)

SCENARIO_HELP = "A preset name (see `trackjam presets`) or a YAML/TOML scenario file."
SET_HELP = "Override a scenario key, dotted: --set antenna.opening_angle_deg=120 (repeatable)."


def _version(value: bool) -> None:
    if value:
        from trackjam import __version__

        typer.echo(f"trackjam {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version and exit."),
) -> None:
    """Cooperative tracking and radio-jamming of a rogue drone by a team of pursuer drones."""


def _full_disk(err: OSError) -> str | None:
    """The line for an output that a full disk refused (`> /dev/full`), else None."""
    return f"cannot write the output: {err.strerror}" if err.errno in (errno.ENOSPC, errno.EDQUOT) else None


def _fail(message: str) -> None:
    from trackjam.errors import printable

    typer.echo(f"trackjam: error: {printable(message)}", err=True)
    raise typer.Exit(2)


_said_interrupted = False  # a command's Ctrl-C was reported (user_errors): typer's exit status 130 alone was not
_said_terminated = False  # a SIGTERM was reported by the command (`run` while writing): the entry point need not


def user_errors(fn: Callable) -> Callable:
    """Turn the errors a user can fix into one line and exit status 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from trackjam.errors import TrackjamError

        try:
            from trackjam.config.limits import check_environment

            check_environment()  # before the command loads numba, which reads NUMBA_NUM_THREADS
            return fn(*args, **kwargs)
        except TrackjamError as err:
            _fail(str(err))
        except MemoryError:
            # past the estimate of config/limits.py (which counts the largest arrays, not all of
            # them): one line, not a traceback of 200; the run's folder is written whole or not at all
            from trackjam.config.limits import memory_budget

            _fail(f"out of memory (this process may use about {2 * memory_budget() / 1e9:.3g} GB); lower the "
                  "scenario's sizes: filter.particles, filter.birth_particles, steps, agents.initial, "
                  "sensor.clutter_rate")
        except OSError as err:
            # a path the user gave that the system refuses where no check looked (a name past 255
            # bytes fails even Path.exists()), or the standard output on a full disk (`> /dev/full`);
            # any other OSError without a file name is not the user's
            if err.filename is not None:  # a path of thousands of characters is shown by its two ends
                from trackjam.errors import ends

                _fail(f"{ends(str(err.filename))}: {err.strerror or err}")
            if _full_disk(err):
                _fail(_full_disk(err))
            raise
        except (KeyboardInterrupt, SystemError) as err:
            ended = _cause(err, SystemExit)  # a SIGTERM whose handler ran inside a callback of compiled code
            if isinstance(err, SystemError) and ended is not None:
                raise SystemExit(ended.code) from None
            if not interrupted(err) and not _ctrl_c_came():  # a SystemError that no Ctrl-C caused
                raise
            _say_interrupted(err)
        except Exception as err:
            # an error a Ctrl-C or a SIGTERM caused: one that landed while matplotlib's compiled
            # module was loading surfaced as "ImportError: initialization failed", a traceback
            # (typer's Exit of a Ctrl-C already said is no such error)
            if isinstance(err, (typer.Exit, typer.Abort)):
                raise
            if interrupted(err) or _ctrl_c_came():  # the latter: a KeyboardInterrupt a compiled module swallowed
                _say_interrupted(err)
            if _terminated_by(err) is None:
                raise
            _say_terminated(err, "trackjam: terminated")

    return wrapper


def _ctrl_c_came() -> bool:
    """Whether a Ctrl-C reached this process under the entry point (:data:`trackjam.console.ctrl_c_came`):
    an error after it is the Ctrl-C's, even when a compiled module swallowed its KeyboardInterrupt
    and failed in its own words (matplotlib: "incompatible function arguments")."""
    console = sys.modules.get("trackjam.console")
    return bool(getattr(console, "ctrl_c_came", False))


def _say_interrupted(err: BaseException) -> None:
    """The one line of a Ctrl-C and exit status 130. When the Ctrl-C landed in the import of a
    compiled module, that module is half made, and the interpreter's own exit aborted on it
    ("Fatal Python error: PyThreadState_Get", status 134): the process then ends at once, its
    output flushed, once every `with` block on the way here has done its cleaning."""
    global _said_interrupted
    _said_interrupted = True
    typer.echo("trackjam: interrupted", err=True)
    _end_now_if_in_import(err, 130)
    raise typer.Exit(130)


def _say_terminated(err: BaseException, line: str) -> None:
    """The one ``line`` of a SIGTERM (or SIGHUP) and exit status 143, for an error the signal's
    SystemExit caused; like :func:`_say_interrupted`, the process ends at once when the signal
    landed in the import of a compiled module."""
    global _said_terminated
    _said_terminated = True
    typer.echo(line, err=True)
    _end_now_if_in_import(err, TERMINATED)
    raise SystemExit(TERMINATED) from None


def _end_now_if_in_import(err: BaseException, status: int) -> None:
    """End the process at once with ``status``, its output flushed, when the signal behind ``err``
    landed in the import of a compiled module (see :func:`_say_interrupted`); else return."""
    if _cause(err, ImportError) is None:
        return
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(status)


def _terminated_by(err: BaseException) -> BaseException | None:
    """The SIGTERM (the SystemExit(143) of its handler) in ``err``'s chain, or None."""
    ended = _cause(err, SystemExit)
    return ended if ended is not None and ended.code == TERMINATED else None


def _cause(err: BaseException, kind: type) -> BaseException | None:
    """The first exception of type ``kind`` in ``err``'s chain of causes and contexts, or None."""
    seen = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, kind):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None


def interrupted(err: BaseException) -> bool:
    """``err`` stands for a Ctrl-C: a KeyboardInterrupt, or an error it caused. A SIGINT whose
    Python handler runs inside a callback of compiled numba code (numba unpickling a constant)
    surfaces as SystemError("... returned a result with an exception set"), chained from the
    KeyboardInterrupt."""
    return _cause(err, KeyboardInterrupt) is not None


def _stopped_by_signal(err: BaseException) -> str | None:
    """What a signal made of `run`'s write, for its one line: "interrupted" for a Ctrl-C (the
    KeyboardInterrupt itself), "terminated" for a SIGTERM (its handler's SystemExit(143), or an
    error it caused: an ImportError when it landed while matplotlib's compiled module loaded);
    None for anything else, an error a Ctrl-C caused included (:func:`user_errors` says that one)."""
    if isinstance(err, KeyboardInterrupt):
        return "interrupted"
    return "terminated" if _terminated_by(err) is not None else None


def _end_stopped_write(err: BaseException, line: str) -> NoReturn:
    """Say ``line`` (what the folder holds now) for ``err``, a signal's end of `run`'s write
    (:func:`_stopped_by_signal`), and end with its status: a Ctrl-C exits 130; a SIGTERM's own
    SystemExit(143) goes on as it is; an error a SIGTERM caused ends as :func:`_say_terminated`
    ends one (at once when it landed in a compiled module's import)."""
    global _said_interrupted, _said_terminated
    if isinstance(err, KeyboardInterrupt):
        typer.echo(line, err=True)
        _said_interrupted = True
        raise typer.Exit(130) from None
    if not isinstance(err, SystemExit):
        _say_terminated(err, line)
    _said_terminated = True
    typer.echo(line, err=True)
    raise err


# the longest paths a command writes under its --out (checked with --out itself, before any work):
# a run's file in its staging folder (trackjam.simulation.output's STAGING, mkdtemp's 8 random
# characters, its longest file name), a sweep's trial file's temporary name (at most 20,000 runs:
# configuration and trial numbers of 5 digits at most)
RUN_UNDER = ".trackjam-staging.xxxxxxxx.tmp/measurements.parquet"
EXPERIMENT_UNDER = "trials/.c20000-t20000.parquet.xxxxxxxx.tmp.parquet"


def _path_option(option: str, value: str | None, what: str = "folder", under: str | None = None) -> Path | None:
    """The path an option names; an empty one is refused (``Path("")`` is the current folder, into
    which `--out ''` wrote a run's files without a word). ``what`` the option names: a folder or a file.
    ``under``: the longest path the command writes in the folder (relative), or for a file None,
    its temporary name: one the system cannot hold is refused too, before any work."""
    if value is None:
        return None
    if not value:
        from trackjam.errors import ConfigError

        default = f", or drop {option} for the default one" if what == "folder" else ""
        raise ConfigError(f"{option} '': an empty path; name a {what}{default}")
    from trackjam.files import temporary_beside, too_long

    made = Path(value) / under if under is not None else temporary_beside(Path(value)) if what == "file" else None
    if why := too_long(Path(value), made):
        from trackjam.errors import ConfigError, ends

        raise ConfigError(f"{option} {ends(value)}: {why}")
    return Path(value)


def _load(scenario: str, overrides: list[str] | None, seed: int | None = None):
    """The validated scenario and the warning ``config.loading.literal_note`` gives for it (or None); the
    caller warns by :func:`_warn` once its other checks have passed, so that a refused command
    prints its one error line and nothing else."""
    from trackjam.config.loading import load_scenario_noted

    if seed is not None:  # checked here, else the preset or file was blamed for it
        from trackjam.config.limits import check_seed

        check_seed(seed)
    fields = {} if seed is None else {"seed": seed}
    return load_scenario_noted(scenario, overrides or [], **fields)


def _warn(s, note: str | None) -> None:
    """One line on stderr per suspicious but legal value of ``s``, and ``note`` (the warning for a
    file that leaves out the three practical choices, :func:`_load`'s) if any."""
    from trackjam.config.warnings import scenario_warnings

    for line in scenario_warnings(s) + ([note] if note else []):
        typer.echo(f"trackjam: warning: {line}", err=True)


def _runnable(s, overrides: list[str] | None) -> None:
    """Refuse, in one line, an option the engine that runs ``s`` does not simulate (several
    targets run on the swarm engine, which reads fewer options): `validate` says so as `run` would,
    blaming the ``--set`` that set it as a bad value is."""
    if len(s.target_list) > 1:  # simulation.build's several_targets, without importing the engine (0.5 s)
        from trackjam.simulation.build import check_swarm_options

        check_swarm_options(s, overrides)


@app.command()
@user_errors
def presets() -> None:
    """List the built-in scenario presets, each with what it is for."""
    from trackjam.config import load_scenario, preset_names
    from trackjam.config.loading import preset_summary

    for name in preset_names():
        s = load_scenario(name)
        typer.echo(
            f"{name:<20} {counted(s.n_agents, 'agent')}, {counted(s.steps, 'step')}, solver {s.control.solver}, "
            f"theta_a {s.antenna.opening_angle_deg:g} deg: {preset_summary(name)}"
        )


@app.command("show-config")
@user_errors
def show_config(
    scenario: str = typer.Argument("paper-fig3", help=SCENARIO_HELP),
    set_: Optional[list[str]] = typer.Option(None, "--set", metavar="KEY=VALUE", help=SET_HELP),
) -> None:
    """Print the fully resolved scenario as YAML."""
    from trackjam.config import scenario_to_yaml

    s, note = _load(scenario, set_)
    _runnable(s, set_)  # what `validate` and `run` refuse is not printed as a scenario to run
    _warn(s, note)
    typer.echo(scenario_to_yaml(s), nl=False)


@app.command()
@user_errors
def validate(
    scenario: str = typer.Argument(..., help=SCENARIO_HELP),
    set_: Optional[list[str]] = typer.Option(None, "--set", metavar="KEY=VALUE", help=SET_HELP),
) -> None:
    """Check a scenario (a preset or a file); print `ok` or one line naming the key and the problem."""
    s, note = _load(scenario, set_)
    _runnable(s, set_)
    _warn(s, note)
    typer.echo(f"ok: {s.name}, {counted(s.n_agents, 'agent')}, {counted(s.steps, 'step')}")


def _step_progress(total: int, label: str):
    """A rich bar on a terminal, one plain line per step otherwise. Returns (callback, close)."""
    if sys.stdout.isatty():
        from rich.markup import escape
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        bar = Progress(TextColumn(escape(label)), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
        task = bar.add_task(label, total=total)
        bar.start()
        return (lambda t, n: bar.update(task, completed=t)), bar.stop

    def line(t: int, n: int) -> None:
        print(f"{label}: step {t}/{n}", flush=True)

    return line, lambda: None


def _warm_up(s) -> None:
    """Load (or, on a first run, compile) the scenario's kernels before the timed run, saying so
    (numba is silent). The line cannot know which it will be: it said "compiling" every time."""
    from trackjam.simulation.warmup import warm_up

    message = "loading the compiled kernels (compiling them on the first run only, 6-12 s)"
    if sys.stdout.isatty():
        from rich.console import Console

        with Console(stderr=True).status(message):
            warm_up(s)
    else:
        print(message, flush=True)
        warm_up(s)


@app.command()
@user_errors
def run(
    scenario: str = typer.Argument("paper-fig3", help=SCENARIO_HELP),
    seed: Optional[int] = typer.Option(None, "--seed", help="Seed of every random choice (default: the scenario's)."),
    out: Optional[str] = typer.Option(None, "--out", metavar="<path>", help="Output folder (default: runs/<name>-seed<seed>)."),
    set_: Optional[list[str]] = typer.Option(None, "--set", metavar="KEY=VALUE", help=SET_HELP),
    figures: bool = typer.Option(True, "--figures/--no-figures", help="Write run.png and replay.html."),
) -> None:
    """Run one scenario end to end and write its logs, figure and 3D replay."""
    out = _path_option("--out", out, under=RUN_UNDER)
    s, note = _load(scenario, set_, seed)
    _runnable(s, set_)
    default = out is None
    out = out or Path("runs") / f"{s.name}-seed{s.seed}"
    from trackjam.simulation.output import check_out_dir

    check_out_dir(out, s, default)  # before any work: nothing is computed for a folder we cannot use
    _warn(s, note)  # after every refusal: a refused run prints its one line and nothing else

    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from trackjam.simulation.loop import simulate
    from trackjam.simulation.output import WROTE, write_run

    _warm_up(s)
    cb, close = _step_progress(s.steps, s.name)
    try:
        result = simulate(s, progress=cb)
    finally:
        close()
    from trackjam.errors import printable

    existed = out.is_dir()

    def waiting() -> None:
        typer.echo(f"trackjam: another run is writing into {printable(str(out))}; waiting for it to finish", err=True)

    try:
        files = write_run(result, out, figures=figures, on_wait=waiting, checked=True, default=default)
    except BaseException as err:
        how = _stopped_by_signal(err)
        if how is None:
            raise
        if getattr(err, WROTE, False):  # it came while the last renames held it back: the run is there
            held = f"after writing {printable(str(out))} in full"
        elif existed:  # else the write removed the folders it made
            held = f"while writing {printable(str(out))}; nothing in it was changed"
        else:
            held = f"while writing {printable(str(out))}; nothing was written"
        _end_stopped_write(err, f"trackjam: {how} {held}")
    m = result.summary
    if "n_targets" in m:
        Console(width=100).print(_swarm_table(s, m))
        typer.echo(f"wrote {len(files)} files to {printable(str(out))}")
        return
    table = Table(title=escape(f"{s.name}  seed {s.seed}  solver {s.control.solver}"))
    table.add_column("metric")
    table.add_column("value", justify="right")
    add = lambda label, value: table.add_row(escape(label), value)  # noqa: E731
    add(_ospa_label(s), f"{m['ospa_mean']:.2f}")
    add("jamming incidents per agent", " ".join(str(v) for v in m["jamming_incidents"]))
    add("mean power at target [W]", f"{m['target_received_w_mean']:.3g}")
    add("mean interference at agents [W]", f"{m['agent_received_w_mean']:.3g}")
    add("mean transmit power [W]", f"{m['transmit_w_mean']:.3g}")
    for label, value in _quality_rows(m):
        add(label, value)
    if s.control.close_in is not None:
        add(f"steps closed in (control.close_in {s.control.close_in:g})", str(m["closed_in_steps"]))
    add("time per step [ms]", f"{1000 * m['step_s_mean']:.1f}")
    if m.get("downed_at") is not None:
        add("target downed at step", str(m["downed_at"]))
    Console(width=100).print(table)
    if m["transmit_w_mean"] == 0.0:  # a team that never sent senses nothing: every plan was worth 0
        typer.echo("trackjam: warning: the team never transmitted (mean transmit power 0 W), so no agent sensed "
                   "anything: at these settings no plan was worth more than hovering silent (see the antenna's "
                   "levels, interference limit and r0); its estimates are the cue's, coasted", err=True)
    typer.echo(f"wrote {len(files)} files to {printable(str(out))}")


def _ospa_label(s) -> str:
    """The OSPA row's label with the scenario's own order and cut-off (metrics.ospa_order, ospa_cutoff)."""
    return f"mean OSPA (p={s.metrics.ospa_order:g}, c={s.metrics.ospa_cutoff:g}) [m]"


def _swarm_table(s, m: dict):
    """The closing table of a run with several targets: per target held and downed, the
    multi-target OSPA, incidents and time per step."""
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=escape(f"{s.name}  seed {s.seed}  solver {s.control.solver}  {m['n_targets']} targets"))
    table.add_column("metric")
    table.add_column("value", justify="right")
    add = lambda label, value: table.add_row(escape(label), escape(value))  # noqa: E731
    for k, name in enumerate(m["ids"]):
        downed = m["downed_at"][k]
        add(f"target {name}: held (a track within {m['gate_m']:g} m) / detectable steps",
            f"{m['held_steps'][k]}/{m['detectable_steps'][k]}  {_share(m['held_share'][k])}"
            + ("" if downed is None else f"  downed at step {downed}"))
    add("all targets: held / detectable target-steps",
        f"{m['held_steps_total']}/{m['detectable_steps_total']}  {_share(m['held_share_total'])}")
    add(f"ceiling: a chaser within {m['ceiling_d_m']:g} m, per target (all)",
        " ".join(_share(v) for v in m["ceiling_share"]) + f"  ({_share(m['ceiling_share_total'])})")
    add("steps with a false track (false tracks)", f"{m['false_track_steps']} ({m['false_tracks']})")
    add("label switches per target", " ".join(str(v) for v in m["label_switches"]))
    add(_ospa_label(s), f"{m['ospa_mean']:.2f}")
    add("  its cardinality part [m]", f"{m['ospa_card_mean']:.2f}")
    add("mean |tracks - detectable targets|", f"{m['cardinality_error_mean']:.2f}")
    add("jamming incidents per agent", " ".join(str(v) for v in m["jamming_incidents"]))
    add("targets downed", f"{m['targets_downed']} of {m['n_targets']}")
    add("time per step [ms]", f"{1000 * m['step_s_mean']:.1f}")
    return table


def _share(v: float | None) -> str:
    return "-" if v is None else f"{100 * v:.0f} %"


def _quality_rows(m: dict) -> list[tuple[str, str]]:
    """The run table's track quality judged by the truth (README, "Track quality judged by the
    truth"): a confirmed track that has slipped off the target counts as a false track."""
    gate, n = f"{m['gate_m']:g}", m["detectable_steps"]
    reacq = m["reacquisition_steps"]
    if not reacq:  # a spell counts only between detectable steps (before the first, or at the end, it does not)
        again = "no detectable step" if n == 0 else "no hidden spell between detectable steps"
    else:
        again = ", ".join("never" if r is None else f"after {r}" for r in reacq) + " [steps]"
    first = m["first_acquisition_steps"]
    return [
        (f"held (confirmed, within {gate} m) / detectable steps", f"{m['held_steps']}/{n}  {_share(m['held_share'])}"),
        (f"false track (confirmed, > {gate} m off)", f"{m['false_track_steps']}/{n}  {_share(m['false_track_share'])}"),
        ("missed (not confirmed)", f"{m['missed_steps']}/{n}  {_share(m['missed_share'])}"),
        ("phantom (confirmed, target hidden or absent)", counted(m["phantom_steps"], "step")),
        ("first held [steps after first detectable]", "never" if first is None else str(first)),
        ("re-acquired after each hidden spell", again),
        (f"ceiling: a chaser within {m['ceiling_d_m']:g} m", _share(m["ceiling_share"])),
    ]


@app.command()
@user_errors
def experiment(
    name: str = typer.Argument(..., help="table1 | constraints | solvers | holding | comms | oracles | swarm"),
    trials: int = typer.Option(20, "--trials", help="Trials per configuration (the paper: 20)."),
    steps: int = typer.Option(30, "--steps", help="Steps per trial (the paper: 30)."),
    seed: int = typer.Option(0, "--seed", help="Experiment seed; each trial's seed derives from it."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Local worker processes (default: CPU count)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler address, [SCHEME://]HOST:PORT with tcp (the default), tls, ws or wss."),
    out: Optional[str] = typer.Option(None, "--out", metavar="<path>", help="Output folder (default: runs/experiment-NAME); rerun to resume."),
    set_: Optional[list[str]] = typer.Option(None, "--set", metavar="KEY=VALUE", help=SET_HELP),
    grid: Optional[str] = typer.Option(None, "--grid", help="swarm only: TARGETSxAGENTS, e.g. 1-4x3-6 (the default)."),
) -> None:
    """Run a Monte Carlo experiment, the paper's (table1, constraints) or ours (resumable; local pool or Dask)."""
    from trackjam.experiments.cli import experiment_command

    out = _path_option("--out", out, under=EXPERIMENT_UNDER)
    experiment_command(
        name=name,
        trials=trials,
        steps=steps,
        seed=seed,
        workers=workers,
        scheduler=scheduler,
        out=out or Path("runs") / f"experiment-{name}",
        overrides=set_ or [],
        grid=grid,
    )


@app.command()
@user_errors
def bench(
    quick: bool = typer.Option(False, "--quick", help="Fewer repetitions, for a smoke check."),
    json_out: Optional[str] = typer.Option(None, "--json", metavar="<path>", help="Also write the figures as JSON here."),
    only: Optional[list[str]] = typer.Option(None, "--only", help="filter | control | run | env (repeatable)."),
) -> None:
    """Measure the speed of the filter, the solvers, a whole run and the learning environment."""
    from trackjam.benchmarks.report import run_benchmarks

    run_benchmarks(quick=quick, json_out=_path_option("--json", json_out, "file"), only=only or [])

