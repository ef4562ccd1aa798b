"""Writing a run to its output folder, safely.

The folder is checked before any work starts: a file, an unwritable place, or a non-empty
folder that holds anything but an earlier run of the very same resolved scenario is refused,
so nothing of the user's is overwritten. The run's files are written into a hidden staging
folder inside it and moved into place together at the end, with Ctrl-C and SIGTERM held back
for those few renames: a write that is interrupted or fails (a full disk) leaves the folder as
it was, an earlier run's files whole and none of the new ones, and the folders the write made
are removed again. Only a SIGKILL during the renames, or a rename the file system refuses
(said in the one line), can leave some files new and others old. What a SIGKILL leaves behind
(the hidden staging folder, or a temporary file of an earlier version) is ours, ignored by the
check and removed by the next write. Two runs writing into one folder take turns under a lock
on it (:func:`_folder_locked`), and the second checks the folder again once it has the lock.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Callable

try:
    import fcntl
except ImportError:  # not on Windows: two runs into one folder there are not told apart
    fcntl = None

from trackjam.arguments import text_path
from trackjam.errors import ConfigError, OutputError, shortened
from trackjam.files import (
    TEMP_MARK,
    check_writable,
    existing_folder,
    is_temporary_of,
    kind_of,
    remove_leftover,
    taken_by,
)
from trackjam.simulation.build import figure_settings, scenario_text

if TYPE_CHECKING:
    from trackjam.simulation.build import Scenario

RUN_FILES = (
    "scenario.yaml",
    "summary.json",
    "steps.parquet",
    "agents.parquet",
    "measurements.parquet",
    "targets.parquet",  # several targets (the swarm engine)
    "tracks.parquet",
    "run.png",
    "replay.html",
)
STAGING = ".trackjam-staging."  # prefix of the hidden folder a run's files are written in first
LOCK_TRIES = 20  # the times a run waiting for its folder finds it removed before it gives up
WROTE = "trackjam_wrote"  # set on a Ctrl-C or SIGTERM that came once the run's files were all in place


def check_out_dir(out: Path, scenario: Scenario, default: bool = False, meanwhile: bool = False) -> None:
    """Refuse an output folder that would lose or corrupt something (one-line ConfigError).

    ``default``: the user gave no ``--out`` and ``out`` is the one named after the scenario's
    name and seed, which the message says (it blamed a ``--out`` nobody typed). ``meanwhile``:
    the folder was checked before the run, so what is refused now was made there while the run
    ran (another process writing there), which the message says."""
    out = Path(out)
    where = f"{out} (the default output folder, from the scenario's name and seed)" if default else f"--out {out}"
    note = ", made there while this run ran (nothing of this run was written)" if meanwhile else ""
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{where}: is {kind_of(out)}, not a folder{note}")
    if out.is_dir():
        entries = [p.name for p in out.iterdir() if not _leftover(p)]
        if entries:
            previous = out / "scenario.yaml"
            text = scenario_text(scenario).encode()
            # compared as bytes, size first: the file there may be binary, or huge
            same = previous.is_file() and previous.stat().st_size == len(text) and previous.read_bytes() == text
            strangers = sorted(set(entries) - set(RUN_FILES))
            if not same or strangers:
                # the same scenario's run beside other entries is named by those entries
                what = ("another scenario's run" if previous.is_file() and not same
                        else f"other files ({shortened(', '.join(strangers), 60)})" if strangers else "other files")
                fix = "pass --out FOLDER or change the scenario's `name`" if default else "choose a new or empty folder"
                raise ConfigError(f"{where}: folder is not empty and holds {what}{note}; {fix}")
            # an earlier run of this scenario, to be replaced: a name of ours that is not a file
            # (a folder) would fail only once the run is done and the files before it rewritten
            for name in RUN_FILES:
                if what := taken_by(out / name):
                    fix = "pass --out FOLDER" if default else "choose another --out"
                    raise ConfigError(f"{where}: {name} is {what}, not a file{note}; move it away or {fix}")
    check_writable(out if out.is_dir() else existing_folder(out, where), where)


def _leftover(p: Path) -> bool:
    """Ours to remove: the staging folder of a write that was killed, or a temporary file of one."""
    if p.name.startswith(STAGING) and p.name.endswith(TEMP_MARK):
        return p.is_dir() and not p.is_symlink()
    return p.is_file() and any(is_temporary_of(p, name) for name in RUN_FILES)


def _remove_leftovers(out: Path) -> None:
    """Remove what killed writes left in ``out`` (:func:`_leftover`)."""
    for p in out.iterdir():
        if _leftover(p):
            remove_leftover(p)


@contextmanager
def _signals_held():
    """Hold Ctrl-C, SIGTERM and SIGHUP back while the staged files are renamed into place, so that
    a folder is not left half old and half new; a signal that came meanwhile acts right after
    (SIGTERM first when several came: one exception can end the command). If the block fails, its
    error is what is raised, and a held Ctrl-C is dropped: the command ends with that error.

    Python runs its signal handlers in the main thread; there the handlers are swapped for one
    that only notes the signal (masking the signal would not do: another thread of the process,
    numba's or BLAS's, may receive it). Elsewhere no Ctrl-C can land in this code. A handler
    set from C (``getsignal`` says None) is left alone, as it could not be put back. Each
    handler is put back even when a signal lands between two of the swaps."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous: dict[int, object] = {}

    def note(signum, frame):
        caught.append(signum)

    held = [signal.SIGTERM, *([signal.SIGHUP] if hasattr(signal, "SIGHUP") else []), signal.SIGINT]
    try:
        for s in held:
            if signal.getsignal(s) is not None:
                previous[s] = signal.signal(s, note)
        yield
    except BaseException:
        _put_back(previous)
        raise
    _put_back(previous)
    for s in held:
        if s in caught:
            signal.raise_signal(s)


def _put_back(previous: dict) -> None:
    """Restore the handlers ``previous`` holds, each one even if a signal lands between them."""
    if not previous:
        return
    s, handler = previous.popitem()
    try:
        signal.signal(s, handler)
    finally:
        _put_back(previous)


@contextmanager
def _folder_locked(out: Path, on_wait: Callable[[], None] | None = None):
    """Hold an exclusive lock (``flock``) on the folder ``out`` while a run's files are written
    into it, so that two runs writing into one folder take turns: the second waits (a few
    seconds at most, and Ctrl-C ends the wait; ``on_wait`` is called when it starts) and then
    finds the first one's run, which it replaces whole if it is of the same scenario. Without
    it the second removed the first's staging folder as a leftover, and the first failed.
    Yields whether the lock is on the folder that is at ``out`` now: False when it was removed
    (or replaced) meanwhile, by a failed write that had made it. A folder that cannot be opened
    or a file system without locks (some network mounts) goes unlocked, as before (True)."""
    try:
        fd = os.open(out, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)) if fcntl is not None else None
    except OSError:
        fd = None
    if fd is None:
        yield True
        return
    try:
        locked = _lock(fd, on_wait)
        yield not locked or _same_folder(out, fd)  # unlocked: as before the lock
    finally:
        os.close(fd)  # and with it the lock


def _lock(fd: int, on_wait: Callable[[], None] | None) -> bool:
    """Lock the open folder ``fd`` exclusively, waiting (``on_wait`` first) while another holds
    it; False on a file system without locks."""
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if on_wait is not None:
                on_wait()
            fcntl.flock(fd, fcntl.LOCK_EX)
    except OSError:
        return False
    return True


def _same_folder(out: Path, fd: int) -> bool:
    """The folder open as ``fd`` is still the one at ``out`` (not removed, nor replaced)."""
    try:
        now, held = os.stat(out), os.fstat(fd)
    except OSError:
        return False
    return (now.st_dev, now.st_ino) == (held.st_dev, held.st_ino)


def _make_folder(out: Path) -> list[Path]:
    """``mkdir -p out``, returning the folders it made, outermost first: exactly those, so that
    a failed write removes no folder that was there before (a path through ``..`` names some
    twice: ``new/../old/run`` makes ``new`` and ``old/run``)."""
    chain = [out, *out.parents]
    k = next(i for i, p in enumerate(chain) if p.is_dir())  # the current folder at worst
    made = []
    for p in reversed(chain[:k]):
        try:
            os.mkdir(p)
        except FileExistsError:
            if not p.is_dir():
                raise
            continue
        made.append(p)
    return made


def _unmake(made: list[Path]) -> None:
    """Remove the folders a failed write made, innermost first, those still empty."""
    for p in reversed(made):
        try:
            p.rmdir()
        except OSError:
            pass


def _stage(result, stage: Path, out: Path, figures: bool) -> list[str]:
    """Write the run's files into the staging folder ``stage``; return their names, in the order
    they are to be moved into ``out`` (``summary.json`` last). A file that cannot be written is
    one :class:`OutputError` naming it in ``out``, where nothing has changed yet."""
    from trackjam.simulation.logs import write_parquet

    names: list[str] = []

    def put(name: str, write: Callable[[Path], None]) -> None:
        try:
            write(stage / name)
        except OSError as err:
            raise OutputError(f"{out / name}: cannot be written ({err.strerror or err}); "
                              f"nothing in {out} was changed") from None
        names.append(name)

    put("scenario.yaml", lambda p: p.write_text(scenario_text(result.scenario)))
    tables = getattr(result, "tables", None) or {
        "steps": result.steps, "agents": result.agents, "measurements": result.measurements}
    for name, columns in tables.items():
        put(f"{name}.parquet", lambda p, columns=columns: write_parquet(columns, p))
    if figures and "tracks" in tables:
        from trackjam.viz.swarm import plot_swarm
        from trackjam.viz.swarm_replay import write_swarm_replay

        fs = figure_settings(result.scenario)
        put("run.png", lambda p: plot_swarm(tables, fs, p))
        put("replay.html", lambda p: write_swarm_replay(tables, fs, p))
    elif figures:
        from trackjam.viz.figure import plot_run
        from trackjam.viz.replay import write_replay

        fs = figure_settings(result.scenario)
        put("run.png", lambda p: plot_run(result.steps, result.agents, fs, p))
        put("replay.html", lambda p: write_replay(result.steps, result.agents, fs, p))
    put("summary.json", lambda p: p.write_text(json.dumps(result.summary, indent=2) + "\n"))
    return names


def write_run(result, out: Path, figures: bool = True, on_wait: Callable[[], None] | None = None, *,
              checked: bool = False, default: bool = False) -> list[Path]:
    """Write a :class:`~trackjam.simulation.loop.RunResult` to ``out``, whole or not at all (the
    module docstring); return the files. ``on_wait`` is called once if another run is writing
    into ``out`` and this one waits for it. A Ctrl-C or SIGTERM held back during the renames is
    raised once they are done, marked with the attribute ``trackjam_wrote`` (:data:`WROTE`).
    ``checked``: the caller checked ``out`` before the run (:func:`check_out_dir`, as `trackjam
    run` does), so a refusal now is of what was made there since, and says so; ``default``: ``out``
    is the default output folder (:func:`check_out_dir`)."""
    # checked before anything is written: a text result was an AttributeError, None or 5 pathlib's
    # TypeError, "" the current folder, and figures="no" drew the figures
    if not hasattr(result, "scenario") or not (hasattr(result, "steps") or hasattr(result, "tables")):
        raise TypeError(f"write_run: result must be what trackjam.simulate returns, got {type(result).__name__}")
    text_path("write_run: out", out, "a folder's path")
    if not isinstance(figures, bool):
        raise TypeError(f"write_run: figures must be True or False, got {type(figures).__name__} {figures!r:.60}")
    out = Path(out)
    check_out_dir(out, result.scenario, default, meanwhile=checked)
    for _ in range(LOCK_TRIES):
        try:
            made = _make_folder(out)
        except OSError as err:
            raise OutputError(f"--out {out}: cannot create the folder ({err.strerror or err})") from None
        with _folder_locked(out, on_wait) as held:
            if held:
                return _write_held(result, out, figures, made, default)
        # the folder was removed while this run waited for it (a write that had made it failed): again
    raise OutputError(f"--out {out}: the folder was removed {LOCK_TRIES} times while this run waited to write into it")



def _write_held(result, out: Path, figures: bool, made: list[Path], default: bool = False) -> list[Path]:
    """The write of :func:`write_run`, holding the folder's lock: the folder checked again (another
    run may have written there meanwhile), the leftovers of killed writes removed (no live
    writer's staging folder is among them), the files staged and renamed into place; on any
    failure the staging folder and the folders this write made are removed, still under the lock."""
    stage = None
    renamed = False
    try:
        check_out_dir(out, result.scenario, default, meanwhile=True)
        _remove_leftovers(out)
        try:
            stage = Path(tempfile.mkdtemp(prefix=STAGING, suffix=TEMP_MARK, dir=out))
        except OSError as err:
            raise OutputError(f"--out {out}: cannot write in the folder ({err.strerror or err})") from None
        names = _stage(result, stage, out, figures)
        with _signals_held():
            for k, name in enumerate(names):  # summary.json last
                try:
                    os.replace(stage / name, out / name)
                except OSError as err:  # a name taken since the check (a folder), a file system's refusal
                    raise OutputError(
                        f"{out / name}: cannot be replaced ({err.strerror or err}); "
                        f"{k} of the run's {len(names)} files were moved into {out} before it") from None
            renamed = True
            shutil.rmtree(stage, ignore_errors=True)
    except BaseException as err:
        if renamed:  # a signal held back during the renames: the run is there, whole
            setattr(err, WROTE, True)
            raise
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        _unmake(made)
        raise
    return [out / name for name in names]
