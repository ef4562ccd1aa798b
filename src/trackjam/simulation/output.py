"""Writing a run to its output folder, safely.

The folder is checked before any work starts: a file, an unwritable place, or a non-empty
folder that holds anything but an earlier run of the very same resolved scenario is refused,
so nothing of the user's is overwritten. Each file is written to a temporary name and renamed;
the hidden temporaries an interrupted write leaves behind (a SIGKILL) are ours, ignored by the
check and removed by the next write. A write that fails (a full disk) is one line, and the files
already there keep their earlier content.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from trackjam.errors import ConfigError, OutputError
from trackjam.files import atomic_write, check_writable, existing_folder, is_temporary_of, kind_of, taken_by
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


def check_out_dir(out: Path, scenario: Scenario, default: bool = False) -> None:
    """Refuse an output folder that would lose or corrupt something (one-line ConfigError).

    ``default``: the user gave no ``--out`` and ``out`` is the one named after the scenario's
    name and seed, which the message says (it blamed a ``--out`` nobody typed)."""
    out = Path(out)
    where = f"{out} (the default output folder, from the scenario's name and seed)" if default else f"--out {out}"
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{where}: is {kind_of(out)}, not a folder")
    if out.is_dir():
        entries = [p.name for p in out.iterdir() if not _leftover(p)]
        if entries:
            previous = out / "scenario.yaml"
            text = scenario_text(scenario).encode()
            # compared as bytes, size first: the file there may be binary, or huge
            same = previous.is_file() and previous.stat().st_size == len(text) and previous.read_bytes() == text
            strangers = sorted(set(entries) - set(RUN_FILES))
            if not same or strangers:
                what = "another scenario's run" if previous.is_file() else "other files"
                fix = "pass --out FOLDER or change the scenario's `name`" if default else "choose a new or empty folder"
                raise ConfigError(f"{where}: folder is not empty and holds {what}; {fix}")
            # an earlier run of this scenario, to be replaced: a name of ours that is not a file
            # (a folder) would fail only once the run is done and the files before it rewritten
            for name in RUN_FILES:
                if what := taken_by(out / name):
                    fix = "pass --out FOLDER" if default else "choose another --out"
                    raise ConfigError(f"{where}: {name} is {what}, not a file; move it away or {fix}")
    check_writable(out if out.is_dir() else existing_folder(out, where), where)


def _leftover(p: Path) -> bool:
    return p.is_file() and any(is_temporary_of(p, name) for name in RUN_FILES)


def write_run(result, out: Path, figures: bool = True) -> list[Path]:
    """Write a :class:`~trackjam.simulation.loop.RunResult` to ``out``; return the files."""
    from trackjam.simulation.logs import write_parquet

    # checked before anything is written: a text result was an AttributeError, None or 5 pathlib's
    # TypeError, "" the current folder, and figures="no" drew the figures
    if not hasattr(result, "scenario") or not (hasattr(result, "steps") or hasattr(result, "tables")):
        raise TypeError(f"write_run: result must be what trackjam.simulate returns, got {type(result).__name__}")
    if not isinstance(out, (str, os.PathLike)) or not str(out):
        raise TypeError(f"write_run: out must be a folder's path, got {type(out).__name__} {out!r:.60}")
    if not isinstance(figures, bool):
        raise TypeError(f"write_run: figures must be True or False, got {type(figures).__name__} {figures!r:.60}")
    out = Path(out)
    check_out_dir(out, result.scenario)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"--out {out}: cannot create the folder ({err.strerror or err})") from None
    for p in out.iterdir():
        if _leftover(p):
            p.unlink(missing_ok=True)
    written = []

    def put(name: str, write: Callable[[Path], None]) -> None:
        try:
            atomic_write(out / name, write)
        except OSError as err:
            raise OutputError(
                f"{out / name}: cannot be written ({err.strerror or err}); "
                f"the {len(written)} files written before it, and any earlier {name}, are intact"
            ) from None
        written.append(out / name)

    put("scenario.yaml", lambda p: p.write_text(scenario_text(result.scenario)))
    tables = getattr(result, "tables", None) or {
        "steps": result.steps, "agents": result.agents, "measurements": result.measurements}
    for name, columns in tables.items():
        put(f"{name}.parquet", lambda p, columns=columns: write_parquet(columns, p))
    if figures and "tracks" in tables:
        from trackjam.viz.swarm import plot_swarm

        put("run.png", lambda p: plot_swarm(tables, figure_settings(result.scenario), p))
    elif figures:
        from trackjam.viz.figure import plot_run
        from trackjam.viz.replay import write_replay

        fs = figure_settings(result.scenario)
        put("run.png", lambda p: plot_run(result.steps, result.agents, fs, p))
        put("replay.html", lambda p: write_replay(result.steps, result.agents, fs, p))
    # last: a new folder without it holds a run interrupted while writing (Ctrl-C, a full disk)
    put("summary.json", lambda p: p.write_text(json.dumps(result.summary, indent=2) + "\n"))
    return written
