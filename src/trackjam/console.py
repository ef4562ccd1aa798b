"""The `trackjam` command's entry point: the command line (:mod:`trackjam.cli`) imported under a
Ctrl-C handler, so that a Ctrl-C while typer and rich load (the first tenth of a second) ends in
the one line and exit status 130 a Ctrl-C gets later, not a KeyboardInterrupt traceback."""

import sys


def main() -> None:
    try:
        from trackjam.cli import app
    except KeyboardInterrupt:
        sys.stderr.write("trackjam: interrupted\n")
        sys.exit(130)
    app(prog_name="trackjam")
