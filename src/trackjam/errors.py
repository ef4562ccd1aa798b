"""Errors a user can fix: the CLI prints them as one line and exits with status 2."""


def shortened(text: str, limit: int) -> str:
    """``text`` for a one-line message: at most ``limit`` characters, cut with "..."."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


class _Enough(Exception):
    pass


def bounded_repr(value, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters with "...", built only that far: a message
    echoing a value of a few kB whose aliases expand it to gigabytes (a list of 2,000 uses of
    a mapping of 500 texts of 1,000 characters) had built the whole repr and run out of memory.
    Lists, tuples, dicts and texts are written piece by piece; an integer past the 4300 digits
    Python prints is named by its size; other values by their own repr."""
    parts: list[str] = []
    size = 0

    def emit(text: str) -> None:
        nonlocal size
        parts.append(text)
        size += len(text)
        if size > limit:
            raise _Enough

    def walk(v) -> None:  # each level writes a bracket first, so it recurses at most limit deep
        kind = type(v)
        if kind in (list, tuple):
            emit("[" if kind is list else "(")
            for k, item in enumerate(v):
                if k:
                    emit(", ")
                walk(item)
            emit("]" if kind is list else ("," if len(v) == 1 else "") + ")")
        elif kind is dict:
            emit("{")
            for k, (key, item) in enumerate(v.items()):
                if k:
                    emit(", ")
                walk(key)
                emit(": ")
                walk(item)
            emit("}")
        elif kind in (str, bytes):
            emit(repr(v) if len(v) <= limit else _head_repr(v, limit + 1))
        elif kind is int:
            try:
                emit(repr(v))
            except ValueError:  # past the digits Python prints
                emit(f"<an integer of about {int(v.bit_length() * 0.30103) + 1} digits>")
        else:
            emit(repr(v))

    try:
        walk(value)
    except _Enough:
        pass
    return shortened("".join(parts), limit)


def _head_repr(v, n: int) -> str:
    """The start of ``repr(v)`` from ``repr(v[:n])``: the quotes are those repr chooses for the
    whole text (double when it holds a single quote and no double one), not for its head."""
    r = repr(v[:n])
    if isinstance(v, str):
        double = "'" in v and '"' not in v
        if double != (r[0] == '"'):
            body = r[1:-1]
            r = f'"{body}"' if double else "'" + body.replace("'", "\\'") + "'"
    return r


def counted(n: int, word: str) -> str:
    """``1 step``, ``3 steps``: a count and its noun, for titles and messages."""
    return f"{n} {word}{'' if n == 1 else 's'}"


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
