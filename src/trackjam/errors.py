"""Errors a user can fix: the CLI prints them as one line and exits with status 2."""


def shortened(text: str, limit: int) -> str:
    """``text`` for a one-line message: at most ``limit`` characters, cut with "..."."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def ends(text: str, keep: int = 60) -> str:
    """``text``, or its first and last ``keep`` characters around "..." when it is longer: a path
    of thousands of characters in a message, where its two ends say which it is."""
    return text if len(text) <= 2 * keep + 3 else f"{text[:keep]}...{text[-keep:]}"


def printable(text: str) -> str:
    """``text`` with its control characters escaped (a newline as ``\\n``): a message echoes the
    user's --set items, paths and file names as given, and a newline split its one line, an
    escape sequence reached the terminal."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class TrackjamError(Exception):
    """Base of the errors that name a user's mistake."""


class ConfigError(TrackjamError, ValueError):
    """A scenario, an option or a file the user gave is not valid."""


class OutputError(TrackjamError):
    """A file of the results could not be written (a full disk, a lost mount); what was written
    before is intact."""
