"""Writing files so that a reader never sees half of one: write to a temporary name beside the
target (a dot file holding ``.tmp``), then rename it into place."""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from pathlib import Path
from typing import Callable, Iterable

from trackjam.errors import ConfigError, shortened

TEMP_MARK = ".tmp"


NAME_MAX, PATH_MAX = 255, 4096  # bytes of one name and of a whole path (Linux's; the name's from os.pathconf where it answers)


def too_long(path: Path, made: Path | None = None) -> str | None:
    """Why the system cannot hold ``path`` (a name past NAME_MAX bytes, or the whole past
    PATH_MAX: even Path.exists() raises on them), for a message; None when it can. ``made``: the
    longest path the command will make for it (a file in a folder's staging folder, a temporary
    name beside a file), checked too: a path that fits but whose files would not failed once the
    work was done (a run's last step, minutes of benchmarks), in a line of 8 kB."""
    if past := _past_limits(path):
        kind, n, limit = past
        return f"too long for the file system: {'a name of ' if kind == 'name' else ''}{n} bytes{' in all' if kind == 'path' else ''}, past its {limit}"
    if made is not None and (past := _past_limits(made)):
        kind, n, limit = past
        what = "the files written in it" if path in made.parents else "its temporary file (written first)"
        return f"too long for the file system: {what} would have a {kind} of {n} bytes, past its {limit}"
    return None


def _past_limits(path: Path) -> tuple[str, int, int] | None:
    """("name", bytes, NAME_MAX) or ("path", bytes, PATH_MAX - 1) of a ``path`` the system cannot hold."""
    text = os.fsencode(os.path.abspath(path))
    try:
        name_max = os.pathconf("/", "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):  # no pathconf (Windows) or no answer
        name_max = NAME_MAX
    longest = max(len(part) for part in text.split(b"/"))
    if longest > name_max:
        return "name", longest, name_max
    if len(text) >= PATH_MAX:
        return "path", len(text), PATH_MAX - 1
    return None


def _temporary_affixes(name: str) -> tuple[str, str]:
    """The prefix and suffix of :func:`atomic_write`'s temporary name for a file ``name``."""
    return f".{name}.", TEMP_MARK + Path(name).suffix


def temporary_beside(path: Path) -> Path:
    """The longest name :func:`atomic_write` gives the temporary file of ``path`` (mkstemp's
    random part is 8 characters)."""
    path = Path(path)
    prefix, suffix = _temporary_affixes(path.name)
    return path.with_name(f"{prefix}{'x' * 8}{suffix}")


def existing_folder(path: Path, where: str) -> Path:
    """The nearest existing path at or above ``path`` (absolute), where a folder to write in
    would be made; a file there, or a symbolic link on the way that leads nowhere (a missing
    target, a loop: no folder can be made through it, and a run found that out only once it
    was done), is refused in one line beginning with ``where``."""
    p = Path(path).absolute()
    while not p.exists():
        if p.is_symlink():
            raise ConfigError(f"{where}: {p} is a symbolic link to {shortened(os.readlink(p), 120)} that leads "
                              "nowhere (a missing target or a loop); no folder can be made there")
        p = p.parent
    if not p.is_dir():
        raise ConfigError(f"{where}: {p} is {kind_of(p)}, not a folder")
    return p


def check_writable(folder: Path, where: str) -> None:
    """Refuse, in one line beginning with ``where``, a folder in which no file can be created: a
    real probe, since os.access says yes to root even on read-only file systems."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        raise ConfigError(f"{where}: no file can be made in {folder} ({err.strerror})") from None


def taken_by(path: Path) -> str | None:
    """What holds a result's name instead of a regular file ("a folder", or "a device or a pipe"),
    said in the one line refusing the output folder; None for a file or no entry."""
    if not path.exists() or path.is_file():
        return None
    return "a folder" if path.is_dir() else "a device or a pipe"


def kind_of(path: Path) -> str:
    """What stands at an existing ``path`` that is not a folder, for a message: ``a file``, or
    :func:`taken_by`'s ``a device or a pipe`` (``--out /dev/null`` is not a file)."""
    return taken_by(path) or "a file"


def special_file(path: Path) -> bool:
    """``path`` is a device, a pipe or a socket: neither a regular file nor a folder. A rename
    onto it would replace the node itself (as root, ``--json /dev/null`` replaced the device)."""
    path = Path(path)
    return path.exists() and not path.is_file() and not path.is_dir()


def atomic_write(path: Path, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it to ``path``.

    The temporary name keeps ``path``'s suffix (writers such as matplotlib infer the format from
    it); on failure it is removed and nothing at ``path`` changes. A device or a pipe at
    ``path`` is not replaced."""
    path = Path(path)
    if special_file(path):  # (a folder the rename itself refuses)
        raise OSError(errno.EINVAL, "not a regular file (a device or a pipe); it is not replaced", str(path))
    prefix, suffix = _temporary_affixes(path.name)
    fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        # mkstemp makes 0600 files; the finished file gets the mode any new file of the user's gets
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def is_temporary_of(p: Path, name: str) -> bool:
    """A leftover of an interrupted :func:`atomic_write` to ``name`` in ``p``'s folder."""
    prefix, suffix = _temporary_affixes(name)
    return p.name.startswith(prefix) and p.name.endswith(suffix)


def remove_leftover(p: Path) -> None:
    """Remove what a killed write left: a temporary file (:func:`is_temporary_of`) or a staging
    folder. A folder that is read-only (an archived run or sweep) keeps it: it harms nothing."""
    try:
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink(missing_ok=True)
    except OSError:
        pass


def remove_temporaries(folder: Path, names: Iterable[str]) -> None:
    """Remove the temporary files that killed :func:`atomic_write` calls to ``names`` left in
    ``folder``; a user's dot file is left alone."""
    names = tuple(names)
    for p in folder.iterdir():
        if p.is_file() and any(is_temporary_of(p, name) for name in names):
            remove_leftover(p)


def current_umask() -> int:
    """The process's umask (reading it means setting it: set it straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
