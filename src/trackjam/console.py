"""The `trackjam` program's entry point (the console script and ``python -m trackjam``): what
belongs to the process rather than to the command line object :data:`trackjam.cli.app`, which
Python code may call too.

- The command line is imported under a Ctrl-C handler, so that a Ctrl-C while typer and rich load
  (the first tenth of a second) ends in the one line and exit status 130 a Ctrl-C gets later, not
  a KeyboardInterrupt traceback.
- SIGTERM (`kill`, a batch system's time limit) raises SystemExit(143): what was being written is
  removed on the way out (a run's staging folder, :mod:`trackjam.simulation.output`; an
  experiment's temporary file, :func:`trackjam.files.atomic_write`), an experiment's pool is
  terminated, and the command ends with one line, `trackjam: terminated`. It ended a run at once,
  status -15, with no word and sometimes a temporary file.
- SIGHUP (a closed terminal, a dropped SSH session) is taken as SIGTERM: it had ended a run at once,
  status 129, with its staging folder left behind.
- Once the command is over, a Ctrl-C changes nothing, and one it caught does not end the process
  by SIGINT after all (:func:`_ending`): the exit status is the command's, 130 after a Ctrl-C.
- A reader that stops early (`trackjam run | head -1`, `2>&1 | head`) does not end the command:
  the standard output and error write through :class:`_PipeSafe`, which points its file
  descriptor at the null device at the first broken pipe, and the command goes on to write its
  files, silently. Without it the first progress line after `head` left raised BrokenPipeError,
  exit status 1, and the run was lost without a word. A closed standard stream (`>&-`) is the
  null device (:func:`_reopened`).
"""

import io
import os
import signal
import sys

TERMINATED = 128 + signal.SIGTERM


class _PipeSafe(io.RawIOBase):
    """A file descriptor's raw writer that takes a broken pipe as the reader's leave: from then
    on the descriptor writes to the null device. Under a text and a buffered layer, so that every
    way to the descriptor (``sys.stdout.buffer``, which click uses when the encoding is ASCII,
    ``writelines``, rich) goes through it."""

    def __init__(self, fd: int) -> None:
        super().__init__()
        self._fd = fd

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._fd

    def isatty(self) -> bool:
        return os.isatty(self._fd)

    def write(self, data) -> int:
        try:
            return os.write(self._fd, data)
        except BrokenPipeError:
            self.to_null()
            return len(data)

    def to_null(self) -> None:
        """Point the descriptor at the null device."""
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, self._fd)
        finally:
            os.close(null)

    def close(self) -> None:  # the descriptor is the process's: never closed here
        self.flush()


def _pipe_safe(stream):
    """``stream`` (sys.stdout or sys.stderr) rebuilt over :class:`_PipeSafe`, with its encoding,
    error handler and buffering; unchanged when it has no file descriptor."""
    try:
        fd = stream.fileno()
        stream.flush()
    except (AttributeError, OSError, ValueError):
        return stream
    buffered = io.BufferedWriter(_PipeSafe(fd))
    # an encoding that lacks a character we print (ASCII under LC_ALL=C with PYTHONUTF8=0: the
    # experiment's "±") shows "?" for it rather than ending the command in a traceback
    errors = "replace" if stream.errors == "strict" or stream.errors == "surrogateescape" else stream.errors
    return io.TextIOWrapper(buffered, encoding=stream.encoding, errors=errors,
                            line_buffering=stream.line_buffering, write_through=stream.write_through)


def _reopened(fd: int, stream):
    """``stream``, or, when the standard stream was closed (`>&-`, `2>&-`: Python then sets it
    to None), a text stream on the null device at the same descriptor, so that the command runs
    and writes its files as when its output is thrown away (it ended with a traceback, `--version`
    too, or with exit status 1 after a run that wrote everything)."""
    if stream is not None:
        return stream
    try:
        os.fstat(fd)
    except OSError:
        null = os.open(os.devnull, os.O_WRONLY)  # the lowest free descriptor: fd itself when it is closed
        if null != fd:
            os.dup2(null, fd)
            os.close(null)
    return io.TextIOWrapper(io.FileIO(fd, "w", closefd=False), encoding="utf-8", line_buffering=True)


def _terminated(signum, frame) -> None:
    raise SystemExit(TERMINATED)


ctrl_c_came = False  # a Ctrl-C reached this process (set by _ctrl_c, read by trackjam.cli.user_errors)


def _ctrl_c(signum, frame) -> None:
    """Python's own Ctrl-C handler (a KeyboardInterrupt), noting first that one came: a compiled
    module may swallow the KeyboardInterrupt and fail in its own words instead (matplotlib's
    `affine_transform` said "incompatible function arguments", a traceback and exit status 1,
    when a Ctrl-C landed in it as a sweep drew its figure), and the command then says the Ctrl-C."""
    global ctrl_c_came
    ctrl_c_came = True
    signal.default_int_handler(signum, frame)


def main() -> None:
    sys.stdout = _pipe_safe(_reopened(1, sys.stdout))
    sys.stderr = _pipe_safe(_reopened(2, sys.stderr))
    signal.signal(signal.SIGTERM, _terminated)
    signal.signal(signal.SIGINT, _ctrl_c)
    if hasattr(signal, "SIGHUP"):  # a closed terminal or a dropped SSH session: ended as by SIGTERM, cleaned up
        signal.signal(signal.SIGHUP, _terminated)
    try:
        try:
            import trackjam.cli as cli
        except KeyboardInterrupt:
            sys.stderr.write("trackjam: interrupted\n")
            sys.exit(130)
        try:
            cli.app(prog_name="trackjam")
        except SystemExit as err:
            if err.code == TERMINATED and not cli._said_terminated:
                sys.stderr.write("trackjam: terminated\n")
            raise
        finally:
            _drain(sys.stdout)
            _drain(sys.stderr)
    except KeyboardInterrupt as err:
        # a Ctrl-C in the instants the command's end took to flush its output: the command's own
        # status if it had ended (the SystemExit the Ctrl-C interrupted), else the one line and 130
        ended = err.__context__
        if not isinstance(ended, SystemExit):
            sys.stderr.write("trackjam: interrupted\n")
            ended = SystemExit(130)
        _drain(sys.stdout)
        _drain(sys.stderr)
        raise ended from None
    finally:
        _ending()


def _ending() -> None:
    """The command is over, its status set: a Ctrl-C from now on changes nothing.

    - Python notes a KeyboardInterrupt that left code run by ``exec`` or ``eval`` of a text (a
      dataclass's ``__init__``, a namedtuple, made as a module loads) as unhandled, even once it
      was caught, and under ``python -m`` ends the process with SIGINT for it, whatever the exit
      status: a Ctrl-C that landed there, said `trackjam: interrupted`, killed the process by
      SIGINT (status -2, not 130; 2 of 94 Ctrl-Cs sent 0 to 1 s after a short sweep's last trial,
      while its figure's modules loaded). The note is cleared by the next such ``exec``: one of
      nothing.
    - SIGINT is ignored from here on (:func:`main` is the program's entry point, not a function to
      call and go on): Python puts back its default action, death by SIGINT, as it shuts down, so a
      Ctrl-C then would end a command that had finished, its files written, by SIGINT.
    """
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except (ValueError, OSError):  # not the main thread (main() called from a thread): no handler of ours
        pass
    exec("")  # clears the note of a KeyboardInterrupt caught since it was made (see above)


def _drain(stream) -> None:
    """Flush what ``stream`` still holds; what an output that refuses it (`> /dev/full`, whose
    one line was said) cannot take goes to the null device, instead of an "Exception ignored"
    traceback and exit status 120 when Python flushes it on the way out."""
    try:
        stream.flush()
    except OSError:
        raw = getattr(getattr(stream, "buffer", None), "raw", None)
        if isinstance(raw, _PipeSafe):
            raw.to_null()
            try:
                stream.flush()
            except OSError:
                pass
