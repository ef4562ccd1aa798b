"""Reading a scenario: a YAML or TOML file or a built-in preset, amended with dotted
``key=value`` overrides; every path ends in :func:`validate_scenario`, so all fail alike, with one
line naming the key and the problem."""

from __future__ import annotations

import difflib
import os
import re
import stat
import tomllib
import typing
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from trackjam.config.model import LongInteger, Scenario
from trackjam.errors import ConfigError, bounded_repr, printable, shortened

MAX_FILE_BYTES = 1_000_000  # a scenario is a few kB; this stops /dev/zero and stray binaries
# values of a scenario once YAML's aliases are expanded: a 1 MB file holds fewer than this, but
# nested aliases (*a of a list of *b of ...) expand a few lines to billions, and copying or
# validating them would never end
MAX_VALUES = 1_000_000
# characters of text (keys and values) once aliases are expanded: a few kB of aliases to one
# mapping of long texts expanded to gigabytes, which a message echoing the value then printed
MAX_TEXT = 2 * MAX_FILE_BYTES
MAX_DEPTH = 50  # levels of nesting; the readers after the parser (copies, validation) recurse
SET_SHOWN = 60  # characters of a --set item a message shows
MAX_SHOWN = 8  # problems one message lists (a list of 20,000 bad entries would be a line of 600 kB)
KEY_SHOWN = 80  # characters of a key a message shows (an unknown key of 100 kB made a line of 100 kB)


class _Loader(yaml.SafeLoader):
    """YAML with these fixes for scenario files: ``1e300`` is a float (YAML 1.1 reads it as a
    string), a key given twice in one mapping is an error instead of silently the last, an
    integer of more digits than Python converts (4300) is a :class:`LongInteger`, which the
    model refuses naming its key, instead of a ValueError from inside the parser, and YAML 1.1's
    numbers that read as another number are not: ``010`` is 10 (not octal 8), ``1:30`` the text
    it is (not 90 in base 60). Merge keys (``<<: *base``) merge as YAML 1.1 says, the keys given
    beside them winning; a set (``!!set``) is refused like binary data."""

    def construct_yaml_int(self, node: yaml.ScalarNode) -> Any:
        text = str(node.value).replace("_", "")
        if ":" in text:  # YAML 1.1's base 60, 1:30 for 90: a text, which a number's key refuses
            return self.construct_scalar(node)
        try:
            if _OCTAL.fullmatch(text):  # YAML 1.1's octal, 010 for 8: decimal, as YAML 1.2 and TOML read it
                return int(text, 10)
            return super().construct_yaml_int(node)
        except ValueError:  # "Exceeds the limit (4300 digits) for integer string conversion"
            return LongInteger(sum(c.isdigit() for c in str(node.value)))

    def construct_yaml_float(self, node: yaml.ScalarNode) -> Any:
        if ":" in str(node.value):  # base 60, 1:30.5 for 90.5
            return self.construct_scalar(node)
        return super().construct_yaml_float(node)

    def _check_keys(self, node: yaml.MappingNode) -> None:
        """Refuse a key given twice in one mapping, or a key that is a list or a mapping."""
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == MERGE_TAG:  # `<<: *base`: merged by SafeLoader, the keys given win
                continue
            key = self.construct_object(key_node, deep=True)
            if isinstance(key, (list, dict)):  # YAML's "? [a, b]" keys; a Python dict cannot hold them
                raise yaml.constructor.ConstructorError(
                    None, None, f"a key must be a name, got a {type(key).__name__} (line {key_node.start_mark.line + 1})",
                    key_node.start_mark,
                )
            if not isinstance(key, str):  # `yes: 3` was "1: ...", `~: 3` "None: ..."; a key of 5000 digits unprintable
                raise yaml.constructor.ConstructorError(
                    None, None, f"a key must be a name, got {bounded_repr(key_node.value)}, which YAML reads as "
                    f"{_kind_of_key(key)}; quote it (line {key_node.start_mark.line + 1})", key_node.start_mark,
                )
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {bounded_repr(key)} (line {key_node.start_mark.line + 1})", key_node.start_mark
                )
            seen.add(key)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        self._check_keys(node)
        return super().construct_mapping(node, deep)

    def flatten_mapping(self, node: yaml.MappingNode) -> None:
        """SafeLoader's merge (``<<``), its sources' keys checked as any mapping's, and the keys
        it copies counted over the whole text: a chain of merges (``a2: {<<: *a1, ...}``,
        ``a3: {<<: *a2, ...}``) copies a number of keys that grows as the square of its length,
        before the size check of the data could count them (8,000 lines took 68 s and 1.25 GB)."""
        for key_node, value_node in node.value:
            if key_node.tag == MERGE_TAG:
                sources = value_node.value if isinstance(value_node, yaml.SequenceNode) else [value_node]
                # counted before anything is checked or copied: `<<: [*m, *m, ...]` 150,000 times
                # over a mapping of 5,000 keys had checked the same keys for each use, for minutes
                self._merged = getattr(self, "_merged", 0) + sum(
                    len(source.value) for source in sources if isinstance(source, yaml.MappingNode))
                if self._merged > MAX_VALUES:
                    raise TooLarge(f"its merge keys (<<) copy more than {MAX_VALUES:,} keys; a scenario has a few hundred")
                for source in {id(source): source for source in sources}.values():
                    if isinstance(source, yaml.MappingNode):
                        self._check_keys(source)
        super().flatten_mapping(node)
        self._merged = getattr(self, "_merged", 0) + len(node.value)
        if self._merged > MAX_VALUES:
            raise TooLarge(f"its merge keys (<<) copy more than {MAX_VALUES:,} keys; a scenario has a few hundred")

    def construct_yaml_binary(self, node: yaml.ScalarNode) -> Any:
        # bytes passed as text: `name: !!binary aGVsbG8=` named the run "hello", without a word
        raise yaml.constructor.ConstructorError(
            None, None, f"binary data (!!binary) is not a scenario value (line {node.start_mark.line + 1})",
            node.start_mark,
        )

    def construct_yaml_set(self, node: yaml.MappingNode) -> Any:
        # `radial_steps: !!set {1, 3}` was read as a list in the set's own order
        raise yaml.constructor.ConstructorError(
            None, None, f"a set (!!set) is not a scenario value; give a list (line {node.start_mark.line + 1})",
            node.start_mark,
        )


def _kind_of_key(key: Any) -> str:
    if key is None:
        return "null"
    if isinstance(key, bool):
        return "a boolean"
    if isinstance(key, (int, float)):
        return "a number"
    return f"a {type(key).__name__}"


_OCTAL = re.compile(r"[-+]?0[0-7]+")
MERGE_TAG = "tag:yaml.org,2002:merge"
_Loader.add_constructor("tag:yaml.org,2002:int", _Loader.construct_yaml_int)
_Loader.add_constructor("tag:yaml.org,2002:float", _Loader.construct_yaml_float)
_Loader.add_constructor("tag:yaml.org,2002:binary", _Loader.construct_yaml_binary)
_Loader.add_constructor("tag:yaml.org,2002:set", _Loader.construct_yaml_set)
_EXPONENT_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$")  # 1e3, 2.5E-4
_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _EXPONENT_FLOAT, list("-+0123456789"))


class _Dumper(yaml.SafeDumper):
    """Writes what :class:`_Loader` reads back as written: a text that the loader would read as a
    number (``"1e3"``: PyYAML's YAML 1.1 takes it for text and wrote it bare) is quoted."""


_Dumper.add_implicit_resolver("tag:yaml.org,2002:float", _EXPONENT_FLOAT, list("-+0123456789"))


class TooLarge(yaml.YAMLError):
    """A YAML or TOML text whose values, aliases expanded, are more than ``MAX_VALUES`` or nest
    deeper than ``MAX_DEPTH``."""


def _check_size(data: Any) -> None:
    """Count the values of ``data`` and the characters of its texts (keys too) as its readers
    see them (an alias counts once per use), stopping at ``MAX_VALUES`` values or ``MAX_TEXT``
    characters: a shared list is walked as often as it is used, so the count costs at most
    ``MAX_VALUES`` steps however far the aliases would expand."""
    stack, seen, text = [(data, 0)], 0, 0
    while stack:
        node, depth = stack.pop()
        seen += 1
        if seen > MAX_VALUES:
            raise TooLarge(
                f"its aliases (*name) expand to more than {MAX_VALUES:,} values; a scenario has a few hundred"
            )
        if depth > MAX_DEPTH:
            raise _too_deep()
        if isinstance(node, dict):
            text += sum(len(k) for k in node if isinstance(k, str))
            stack.extend((v, depth + 1) for v in node.values())
        elif isinstance(node, list):
            stack.extend((v, depth + 1) for v in node)
        elif isinstance(node, str):
            text += len(node)
        if text > MAX_TEXT:
            raise TooLarge(f"it holds more than {MAX_TEXT:,} characters of text, its aliases (*name) expanded; "
                           "a scenario has a few thousand")


def _too_deep() -> TooLarge:
    return TooLarge(f"nested more than {MAX_DEPTH} levels deep; a scenario nests a few")


def _parsed(parse: typing.Callable[[str], Any], text: str) -> Any:
    """``parse(text)`` (YAML or TOML) refused when too large or too deep (:func:`_check_size`)."""
    try:
        data = parse(text)
    except RecursionError:  # the parsers recurse once per level: [[[[... 100,000 deep
        raise _too_deep() from None
    _check_size(data)
    return data


def _yaml(text: str) -> Any:
    return _parsed(lambda t: yaml.load(t, Loader=_Loader), text)  # noqa: S506 (a SafeLoader)


def _model_in(annotation: Any) -> Any:
    """The pydantic model an annotation holds, looking through Optional, unions and lists
    (``list[Target] | None`` gives ``Target``); None when it holds none."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return next((m for a in typing.get_args(annotation) if (m := _model_in(a)) is not None), None)


def _section_keys(loc: tuple) -> list[str]:
    """The keys the section at ``loc`` accepts (empty when ``loc`` is not a section); an index
    into a list of sections (``targets.0``) stays in the list's section."""
    model: Any = Scenario
    for part in loc:
        if isinstance(part, int):
            continue
        fields = getattr(model, "model_fields", {})
        if part not in fields:
            return []
        model = _model_in(fields[part].annotation)
    return list(getattr(model, "model_fields", {}))


def _unknown_key(loc: tuple) -> str:
    if loc == ("base",):  # read from a file before the overrides; a --set or keyword comes after it
        return "unknown key here (base, the preset a scenario file starts from, is read from the file alone)"
    close = difflib.get_close_matches(str(loc[-1]), _section_keys(loc[:-1]), n=1, cutoff=0.6)
    if not close:
        return "unknown key"
    return f"unknown key (did you mean {'.'.join(map(str, (*loc[:-1], close[0])))}?)"


# what the items of a fixed-length list are, by its key's last name and length (else by length)
_TUPLE_ITEMS = {
    ("initial", 6): "values (x, y, z, vx, vy, vz)",
    ("noise_std", 3): "standard deviations (range, azimuth, inclination)",
    ("occlusions", 2): "steps (first, last)",
}


def _tuple_length(loc: tuple, e: dict, lengths: dict[tuple, int]) -> bool:
    """Note in ``lengths`` the length a fixed-length list at ``loc`` expects, when ``e`` says it
    has too few items (pydantic: "Field required" per missing item) or too many; True if so."""
    if e["type"] == "missing" and loc and isinstance(loc[-1], int) and isinstance(e.get("input"), (list, tuple)):
        lengths[loc[:-1]] = max(lengths.get(loc[:-1], 0), loc[-1] + 1)
        return True
    if e["type"] == "too_long" and (e.get("ctx") or {}).get("field_type") == "Tuple":
        lengths[loc] = e["ctx"]["max_length"]
        return True
    return False


def _length_message(loc: tuple, expected: int, got: Any) -> str:
    name = next((p for p in reversed(loc) if isinstance(p, str)), "")
    items = _TUPLE_ITEMS.get((name, expected), "coordinates (x, y, z)" if expected == 3 else "items")
    return f"expected {expected} {items}, got {len(got)}"


def _errors(err: ValidationError) -> list[tuple[str, str]]:
    """(dotted key or "", message) of every problem pydantic found; a fixed-length list of the
    wrong length is one problem saying so (pydantic: "agents.initial.1.2: Field required")."""
    out, lengths, inputs = [], {}, {}
    for e in err.errors():
        loc = tuple(p for p in e["loc"] if not str(p).startswith("function-"))
        if _tuple_length(loc, e, lengths):
            where = loc[:-1] if e["type"] == "missing" else loc
            if where not in inputs:
                inputs[where] = e["input"]
                out.append((".".join(str(p) for p in where), where))
            continue
        msg = _unknown_key(loc) if e["type"] == "extra_forbidden" else e["msg"].removeprefix("Value error, ")
        if e["type"] == "model_type" and e["input"] is None:  # `antenna:` and its keys not indented under it
            msg = ("a section, given no value (are its keys indented under it? leave the section out for its "
                   "defaults)")
        elif e["type"] == "model_type":  # pydantic: "Input should be a valid dictionary or instance of Antenna"
            value = e["input"]
            kind = _yaml_kind(value) or (f"the text {shortened(_shown_value(value), 40)}" if isinstance(value, str)
                                         else f"a {type(value).__name__}")
            msg = f"a section of keys (key: value, indented under it), got {kind}"
        if e["type"] == "string_type" and (kind := _yaml_kind(e["input"])):  # name: 2001-12-14, yes, 1e5, 0x10
            key = ".".join(str(p) for p in loc)
            msg += (f" (read as {kind}; a text needs quotes: {key}: \"...\" in a file, --set '{key}=\"...\"' "
                    "on the command line)" if kind != "null" else " (read as null: no value was given)")
        if e["type"] == "literal_error" and isinstance(e["input"], str):  # `Exact`, `grsp`
            choices = re.findall(r"'([^']*)'", str(e.get("ctx", {}).get("expected", "")))
            close = [c for c in choices if c.lower() == e["input"].strip().lower()] or difflib.get_close_matches(
                e["input"].strip().lower(), choices, n=1, cutoff=0.6)
            if close:
                msg += f" (did you mean {close[0]}?)"
        if loc == ("control", "solver") and e["type"] == "literal_error" and _registered(e["input"]):
            msg += (f" ({e['input']!r} is a solver registered from a script: solve(), solver_policy() and "
                    "Planned take it; a scenario takes a solver named in config/model.py's Control.solver)")
        out.append((".".join(str(p) for p in loc), " ".join(msg.split())))
    return [(key, _length_message(msg, lengths[msg], inputs[msg]) if isinstance(msg, tuple) else msg) for key, msg in out]


def _registered(name: Any) -> bool:
    """Whether ``name`` is a solver registered from a script (``control.solve.register``), read
    from the registry only when it is loaded: validating a scenario imports no solver."""
    import sys

    solve = sys.modules.get("trackjam.control.solve")
    return isinstance(name, str) and solve is not None and name in getattr(solve, "SOLVERS", {})


def _yaml_kind(value: Any) -> str | None:
    """What the file's reader (YAML or TOML) or a keyword made of a value where a text was wanted,
    in words; None for the rest."""
    import datetime

    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, (datetime.date, datetime.datetime)):
        return f"the date {value.isoformat()}"
    if value is None:
        return "null"
    return None


def _blamed(key: str, msg: str, overridden: dict[str, str]) -> str | None:
    """Where the problem of ``key`` is blamed: ``overridden``'s label of the ``--set`` item or
    keyword that set ``key`` (or, for a problem between keys, that the message names); else of
    one that wrote into the section ``key`` is a required field of (``--set
    filter.visibility.hide=0.5`` makes a visibility without ``reappear``), or into a section a
    problem between keys names as a key, in backquotes (`` `target` `` beside `` `targets` ``)."""
    named = []  # a problem between keys: the --set items its message names, by where it names them
    for set_key, item in overridden.items():
        if key:
            if key == set_key or key.startswith(set_key + ".") or set_key.startswith(key + "."):
                return item
        elif found := re.search(rf"(^|[\s(]){re.escape(set_key)}\b", msg):
            named.append((found.start(), item))
    if named:  # the key the message starts with, not the --set given first
        return min(named)[1]
    for set_key, item in overridden.items():
        if key and msg == "Field required" and set_key.startswith(key.rpartition(".")[0] + "."):
            return item
        if not key and f"`{set_key.partition('.')[0]}`" in msg:
            return item
    return None


def validate_scenario(data: Any, source: str = "scenario", overridden: dict[str, str] | None = None) -> Scenario:
    """Validate a mapping as a :class:`Scenario`, raising :class:`ConfigError` with one line.

    ``overridden`` maps the dotted keys set by ``--set`` (or a keyword) to the label of what set
    them (:func:`overridden_keys`): a problem with such a key is blamed on it, not on ``source``."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: the scenario must be a mapping of keys, got {type(data).__name__}")
    try:
        return Scenario.model_validate(data)
    except ValidationError as err:
        by_source: dict[str, list[str]] = {}
        problems = _errors(err)
        for key, msg in problems[:MAX_SHOWN]:
            where = _blamed(key, msg, overridden or {}) or source
            by_source.setdefault(where, []).append(f"{shortened(key, KEY_SHOWN)}: {msg}" if key else msg)
        more = f"; and {len(problems) - MAX_SHOWN} more problems" if len(problems) > MAX_SHOWN else ""
        raise ConfigError("; ".join(f"{where}: " + "; ".join(found) for where, found in by_source.items()) + more) from None


def preset_names() -> list[str]:
    files = resources.files("trackjam.presets")
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml"))


def _close_preset(name: str) -> str | None:
    """The preset a misspelt name most likely meant (``paper_fig3``, ``swarm3``, ``Paper-Fig3``),
    as :func:`_unknown_key` hints a key; None for a path or when none is close."""
    if "/" in name or "\\" in name:
        return None
    close = difflib.get_close_matches(name.lower().replace("_", "-"), preset_names(), n=1, cutoff=0.6)
    return close[0] if close else None


# what each built-in preset is for, as `trackjam presets` says it
PRESET_SUMMARIES = {
    "paper-fig3": "the paper's Fig. 3 with our three practical choices (a cued start, existence fused as evidence, "
                  "search when lost)",
    "paper-fig3-literal": "Fig. 3 with the model document read literally; its team never confirms the target",
    "pursuit": "the recommended team: paper-fig3 with antennas pointing where the team aims, as a real team's "
               "must, and the options that hold the target best",
    "swarm-3": "three rogue drones and five pursuers (several targets, ours)",
}


def preset_summary(name: str) -> str:
    """What preset ``name`` is for: :data:`PRESET_SUMMARIES`, else (a file dropped into the presets)
    its first comment line."""
    if name in PRESET_SUMMARIES:
        return PRESET_SUMMARIES[name]
    for line in resources.files("trackjam.presets").joinpath(f"{name}.yaml").read_text().splitlines():
        if line.startswith("#") and line.strip("# "):
            return printable(shortened(line.strip("# "), 100))
    return "(no comment at the top of its file)"


def _preset_data(name: str, seen: tuple[str, ...] = ()) -> dict:
    """A preset's mapping, on top of its own ``base`` if it names one (a file dropped into the
    presets may); a loop of bases is one error."""
    data = _yaml(resources.files("trackjam.presets").joinpath(f"{name}.yaml").read_text())
    if not isinstance(data, dict):
        raise ConfigError(f"preset {name}: the scenario must be a mapping of keys, got {type(data).__name__}")
    if name in seen:
        raise ConfigError(f"preset {name}: base: a loop of bases ({' -> '.join((*seen, name))})")
    return _based(data, f"preset {name}", (*seen, name))


def _read_text(path: Path) -> str:
    """The file's text, read at most ``MAX_FILE_BYTES`` deep (``/dev/zero`` never ends)."""
    if not path.exists():
        if path.is_symlink():  # a loop of links, or a link whose target is gone
            raise ConfigError(f"{path}: a symbolic link that leads to no file (its target is missing, or the "
                              "links form a loop)")
        close = _close_preset(str(path))
        hint = f"did you mean {close}?" if close else "see `trackjam presets`"
        raise ConfigError(f"{path}: no such file (and no preset of that name; {hint})")
    if path.is_dir():
        raise ConfigError(f"{path}: is a folder, not a scenario file")
    if stat.S_ISFIFO(path.stat().st_mode) or stat.S_ISSOCK(path.stat().st_mode):
        raise ConfigError(f"{path}: is a pipe or a socket, not a scenario file")  # opening one may wait forever
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except OSError as err:
        raise ConfigError(f"{path}: cannot be read ({err.strerror or err})") from None
    if len(raw) > MAX_FILE_BYTES:
        raise ConfigError(f"{path}: larger than {MAX_FILE_BYTES // 1_000_000} MB, not a scenario file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise ConfigError(
            f"{path}: not UTF-8 text (byte {err.start} is {raw[err.start]:#04x}); a binary or UTF-16 file?"
        ) from None
    if "\x00" in text:
        raise ConfigError(f"{path}: holds NUL characters; a binary or UTF-16 file?")
    return text


class LongIntegerError(ValueError):
    """A TOML text with an integer of more digits than Python converts; the message says where."""


_TOML_TOKEN = re.compile(r"[A-Za-z0-9_-]+|\"[^\"\n]*\"|'[^'\n]*'|[ \t]+|.", re.DOTALL)


def _toml_key_depth(text: str) -> int:
    """The most parts of a dotted key in a TOML text (``a.b.c`` has 3), or of anything written like
    one, counted in one pass: tomllib takes time and memory that grow as the square of a key's
    parts (40,000 of them, an 80 kB file, took 28 s and 4 GB), before the depth of the data it
    returns could be checked. A text of fewer than MAX_DEPTH dots is not scanned: it gives its
    dots plus one, a bound at most MAX_DEPTH."""
    if text.count(".") < MAX_DEPTH:
        return min(text.count(".") + 1, MAX_DEPTH)
    most = parts = 0
    dot = True  # the last token was a dot (or nothing yet): a name continues the key
    for m in _TOML_TOKEN.finditer(text):
        token = m[0]
        if token[0] in " \t":
            continue
        if token == ".":
            dot = True
            continue
        if dot and (token[0].isalnum() or token[0] in "_-\"'"):
            parts += 1
            most = max(most, parts)
        else:
            parts = 1 if (token[0].isalnum() or token[0] in "_-\"'") else 0
        dot = False
    return most


def _toml(text: str) -> Any:
    if _toml_key_depth(text) > MAX_DEPTH:
        raise _too_deep()
    try:
        return _parsed(tomllib.loads, text)
    except tomllib.TOMLDecodeError:  # a ValueError too
        raise
    except ValueError:  # an integer past Python's 4300 digits, converted inside tomllib
        where = _long_integer(text)
        if where is None:
            raise
        raise LongIntegerError(where) from None


_TOML_LONG = re.compile(r"(?<![\w.\"'])[0-9][0-9_]{4300,}")
_TOML_TABLE = re.compile(r"^\s*\[\[?([^\]]+)\]\]?\s*(?:#.*)?$")
_TOML_KEY = re.compile(r"^\s*([\w.\-\s\"']+?)\s*=")


def _long_integer(text: str) -> str | None:
    """Where the first integer of more than 4300 digits stands in a TOML text, as "KEY: integer
    too large (N digits, line L)", KEY the dotted key of the last key line before it (with its
    table), or None when there is none. A hint, not a parse: tomllib does not say where."""
    for m in _TOML_LONG.finditer(text):  # the first outside a comment (`# seed 111...` is no value)
        if "#" not in text[text.rfind("\n", 0, m.start()) + 1: m.start()]:
            break
    else:
        return None
    table, key = "", ""
    for row in text[: m.start()].split("\n"):
        if t := _TOML_TABLE.match(row):
            table, key = t[1], ""
        elif k := _TOML_KEY.match(row):
            key = k[1]
    # in an inline table, `antenna = {height = 999...}`, the key just before the number
    inner = re.search(r"[{,]\s*([\w\-]+)\s*=\s*$", text[text.rfind("\n", 0, m.start()) + 1: m.start()])
    if inner:
        key = f"{key}.{inner[1]}"
    name = ".".join(p.strip().strip("\"'") for p in f"{table}.{key}".split(".") if p.strip())
    digits = sum(c.isdigit() for c in m[0])
    line = text.count("\n", 0, m.start()) + 1
    return f"{name + ': ' if name else ''}integer too large ({digits} digits, line {line})"


YAML_SUFFIXES = (".yaml", ".yml")
TOML_SUFFIXES = (".toml",)


def _read_file(path: Path) -> dict:
    text = _read_text(path)
    suffix = path.suffix.lower()
    if suffix not in YAML_SUFFIXES + TOML_SUFFIXES:  # a .txt or .json was read as YAML without a word
        if not text:  # /dev/null is empty whatever its name
            raise ConfigError(f"{path}: is empty (write the keys to change, e.g. from `trackjam show-config`)")
        what = f"unknown extension {path.suffix!r}" if path.suffix else "no extension"
        raise ConfigError(f"{path}: {what}: a scenario file ends in .yaml, .yml or .toml (any case)")
    toml = suffix in TOML_SUFFIXES
    try:
        data = _toml(text) if toml else _yaml(text)
    except (TooLarge, LongIntegerError) as err:
        raise ConfigError(f"{path}: {err}") from None
    except tomllib.TOMLDecodeError as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise ConfigError(f"{path}: not valid TOML: {first}") from None
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}: not valid YAML: {_yaml_problem(err, lines=True)}") from None
    # YAML reads a text without a value as None, TOML as an empty table: both are an empty file
    if data is None or (toml and data == {}):
        raise ConfigError(f"{path}: is empty (write the keys to change, e.g. from `trackjam show-config`)")
    if not isinstance(data, dict):
        hint = ""
        if not toml and isinstance(data, str) and _TOML_KEY.match(text.lstrip("\ufeff")):
            hint = f" (`key = value` is TOML: name the file {path.stem}.toml)"
        raise ConfigError(f"{path}: the scenario must be a mapping of keys, got {type(data).__name__}{hint}")
    return data


def _parse_value(text: str) -> Any:
    """A ``--set`` value read as YAML. A value that is not YAML is the text itself, except one
    meant as a flow mapping or list (it starts with ``{`` or ``[``) and one the constructor
    refuses (a key given twice or not a name, an unknown tag): those raise the YAMLError, as in a
    file (read as text, they were refused as "not a valid dictionary", the problem unsaid)."""
    try:
        return _yaml(text)
    except TooLarge:
        raise
    except yaml.constructor.ConstructorError:
        raise
    except yaml.YAMLError:
        if text.lstrip().startswith(("{", "[")):
            raise
        return text


def _yaml_problem(err: yaml.YAMLError, lines: bool = False) -> str:
    """One line of a YAML error: the problem and where, in a ``--set`` value (its column, and its
    line when it has several) or, with ``lines``, in a file (its line and column). PyYAML's text
    begins with the context ("while scanning for the next token"), which says neither."""
    if isinstance(err, yaml.constructor.ConstructorError) and err.problem:
        return " ".join(err.problem.split())  # ours name the key and its line, as in a file
    problem = getattr(err, "problem", None)
    if not problem:
        return " ".join(str(err).split()) or type(err).__name__
    mark = getattr(err, "problem_mark", None)
    hint = "; YAML indents with spaces, not tabs" if "'\\t'" in problem else ""
    if mark is None:
        where = f" ({hint[2:]})" if hint else ""
    elif mark.line or lines:  # a file, or a value of several lines
        where = f" (line {mark.line + 1}, column {mark.column + 1}{hint})"
    else:
        where = f" (column {mark.column + 1}{hint})"
    return " ".join(problem.split()) + where


def set_dotted(data: dict, key: str, value: Any, label: str | None = None) -> None:
    """Set ``data[a][b][c] = value`` for ``key = "a.b.c"``, creating sections as needed.
    ``label`` names what set it in a message (default: ``--set KEY``)."""
    parts = key.strip().split(".")
    shown = shortened(key, SET_SHOWN)  # a key of 100 kB was echoed whole
    if not all(parts):
        raise ConfigError(f"{label or f'--set {shown!r}'}: empty key")
    node = data
    for p in parts[:-1]:
        nxt = node.get(p)
        if nxt is None:
            nxt = {}
            node[p] = nxt
        if not isinstance(nxt, dict):
            raise ConfigError(f"{label or f'--set {shown}'}: {shortened(p, KEY_SHOWN)} is not a section")
        node = nxt
    node[parts[-1]] = value


def override_items(overrides: Any) -> list[str]:
    """The ``--set`` texts as a list (a lone text would be read a character at a time), from any
    iterable in order: not a set or a mapping."""
    if isinstance(overrides, (set, frozenset, typing.Mapping)):
        # a set's order changes from one process to the next (so did which of two items setting
        # one key won), and a mapping would be read by its keys alone
        raise ConfigError(f"overrides: a list of 'key=value' texts, in order (not a {type(overrides).__name__}), "
                          f"got {overrides!r:.80}")
    try:  # (`overrides or []` asked a numpy array for its truth value)
        items = None if isinstance(overrides, (str, bytes)) else [] if overrides is None else list(overrides)
    except TypeError:  # not iterable
        items = None
    if items is None or not all(isinstance(item, str) for item in items):
        raise ConfigError(f"overrides: a list of 'key=value' texts, got {overrides!r:.80}")
    return items


def apply_overrides(data: dict, overrides: list[str] | None) -> dict:
    """Apply dotted ``key=value`` overrides (values parsed as YAML) to a copy of a mapping."""
    data = _deep_copy(data)
    for item in override_items(overrides):
        if "=" not in item:
            raise ConfigError(f"--set {shortened(item, SET_SHOWN)!r}: expected key=value")
        key, _, value = item.partition("=")
        if not all(key.strip().split(".")):  # `--set =5` was "--set '': empty key", the item not shown
            raise ConfigError(f"--set {shortened(item, SET_SHOWN)!r}: an empty key (before the '=' or between two dots)")
        if not _utf8(item):  # bytes the shell passed that are not UTF-8: no key or value is spelt so
            raise ConfigError(f"--set {printable(shortened(item, SET_SHOWN))}: not valid UTF-8 text (a key or a value "
                              "holds bytes that are not UTF-8)")
        try:
            parsed = _parse_value(value)
        except TooLarge as err:
            raise ConfigError(f"--set {shortened(key.strip(), SET_SHOWN)}: {err}") from None
        except yaml.YAMLError as err:
            raise ConfigError(f"--set {shortened(item, SET_SHOWN)}: not valid YAML: {_yaml_problem(err)}") from None
        set_dotted(data, key, parsed)
    return data


def overridden_keys(overrides: list[str] | None) -> dict[str, str]:
    """Dotted key -> ``--set ITEM``, the item that set it (the last one wins, as in
    :func:`apply_overrides`), the label a problem with that key is blamed on."""
    return {item.partition("=")[0].strip(): f"--set {shortened(item, SET_SHOWN)}" for item in overrides or [] if "=" in item}


def blamed_on_set(message: str, overrides: list[str] | None, cause: str | None = None) -> str:
    """A one-line problem ``"key: ..."`` found after validation (an option the engine does not
    simulate) prefixed with the ``--set`` item that set its key, as :func:`validate_scenario`
    blames one; when none set it, with the one that set ``cause`` (the key whose value makes
    ``key``'s a problem: ``targets`` for an option the swarm engine does not simulate); unchanged
    when no ``--set`` set either."""
    key, sep, _ = message.partition(": ")
    overridden = overridden_keys(overrides)
    where = _blamed(key, message, overridden) if sep and " " not in key else None
    if where is None and cause is not None:
        where = _blamed(cause, message, overridden)
    return f"{where}: {message}" if where else message


def _utf8(text: str) -> bool:
    """``text`` is UTF-8 text: no byte the file system's decoding kept as a surrogate."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _deep_copy(d: Any) -> Any:
    if isinstance(d, dict):
        return {k: _deep_copy(v) for k, v in d.items()}
    if isinstance(d, list):
        return [_deep_copy(v) for v in d]
    return d


def _shown_value(value: Any) -> str:
    """A keyword's value for a message: ``errors.bounded_repr`` (built only as far as shown, an
    integer of more digits than Python prints named by its size), on one line (a numpy array's
    repr has several)."""
    return " ".join(bounded_repr(value, SET_SHOWN).split())


def load_scenario_data(name_or_path: str | Path) -> tuple[dict, str]:
    """Raw mapping of a preset name or a file, and a label for messages."""
    data, label, _ = _scenario_source(name_or_path)
    return data, label


def _scenario_source(name_or_path: str | Path) -> tuple[dict, str, dict | None]:
    """:func:`load_scenario_data`'s mapping and label, and the file's own mapping as written
    (before its ``base``; None for a preset), which :func:`literal_note` reads."""
    if not isinstance(name_or_path, (str, os.PathLike)):  # None, 5 or bytes were looked up as file names
        raise ConfigError(f"scenario: a preset name or a path to a YAML/TOML file, got {type(name_or_path).__name__} "
                          f"{shortened(_shown_value(name_or_path), 60)}")
    text = str(name_or_path)
    if not isinstance(name_or_path, str) and text in preset_names() and not Path(text).exists():
        raise ConfigError(f"{text}: no such file; the preset of that name is named by a text, "
                          f"load_scenario({text!r}), not a path")
    if not text:  # Path("") is the current folder: "is a folder" named nothing the user typed
        raise ConfigError(f"{text!r}: an empty scenario name; give a preset (`trackjam presets`) or a YAML/TOML file")
    if isinstance(name_or_path, str) and text in preset_names():
        return _preset_data(text), f"preset {text}", None
    own = _read_file(Path(text))
    return _based(own, text), text, own


# the three practical choices of `paper-fig3` (README, "Our decisions") and their literal values
PRACTICAL_CHOICES = (("filter", "cue", None), ("fusion", "existence", "mean"), ("control", "fallback", "hover"))


def literal_note(own: dict | None, label: str, overrides: list[str] | None, s: Scenario) -> str | None:
    """A warning for a scenario file without ``base`` that leaves all three practical choices to
    the literal defaults, neither the file (``own``, its mapping as written, labelled ``label``)
    nor an override naming one: its team starts knowing nothing and, as `paper-fig3-literal`'s,
    may never confirm the target. None otherwise (a preset, whose ``own`` is None, a file with
    ``base``, one that names a choice, even at its literal value)."""
    if own is None or "base" in own:
        return None
    set_keys = [item.partition("=")[0].strip() for item in override_items(overrides)]
    # several targets run on the swarm engine, which takes fusion.existence: mean only
    several = len(s.target_list) > 1
    choices = [c for c in PRACTICAL_CHOICES if not (several and c[:2] == ("fusion", "existence"))]
    for section, key, literal in choices:
        dotted = f"{section}.{key}"
        if any(k in (section, dotted) or k.startswith(dotted + ".") for k in set_keys):
            return None
        if section in own and not (isinstance(own[section], dict) and key not in own[section]):
            return None
        if getattr(getattr(s, section), key) != literal:
            return None
    if several:
        return (f"{label}: leaves out filter.cue and control.fallback, so the team starts knowing nothing and hovers "
                "when it tracks nothing (the model document read literally); `base: swarm-3` at the top of the file "
                "starts from the preset of several targets instead, and naming either key silences this line")
    return (f"{label}: leaves out filter.cue, fusion.existence and control.fallback, so the team starts knowing "
            "nothing, averages existence and hovers when it tracks nothing (the model document read literally, "
            "as preset paper-fig3-literal, whose team never confirms the target); `base: paper-fig3` at the top "
            "of the file starts from the preset instead, and naming any of the three keys silences this line")


def _based(data: dict, label: str, seen: tuple[str, ...] = ()) -> dict:
    """A file's mapping on top of the preset its ``base`` key names (ours): each section the file
    gives is merged key by key into the preset's, every other value (a list, a number) replaces the
    preset's; the preset's ``name`` is not taken (an unnamed file is ``scenario``), and the
    preset's ``target`` (``targets``) gives way to a file that gives ``targets`` (``target``), not null.
    Without ``base`` the file's keys stand on the defaults, the model document read literally."""
    if "base" not in data:
        return data
    base = data["base"]
    if not isinstance(base, str) or base not in preset_names():
        close = _close_preset(base) if isinstance(base, str) else None
        hint = f" (did you mean {close}?)" if close else ""
        shown = "null (no value)" if base is None else shortened(_shown_value(base), 60)
        raise ConfigError(f"{label}: base: {shown} is not a preset{hint}; base names "
                          f"the built-in preset the file starts from: {', '.join(preset_names())}")
    merged = _preset_data(base, seen)
    merged.pop("name", None)
    own = {k: v for k, v in data.items() if k != "base"}
    for one, other in (("target", "targets"), ("targets", "target")):
        # a null one is none given: `targets: null` is the base's one target, `target: null` beside
        # the base's list sets the one target aside (Scenario), as with --set
        if own.get(one) is not None:
            merged.pop(other, None)
    return _merged(merged, own)


def _merged(under: dict, over: dict) -> dict:
    """``over`` on top of ``under``: sections (mappings on both sides) merged key by key."""
    out = dict(under)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merged(out[key], value)
        else:
            out[key] = value
    return out


def load_scenario(
    name_or_path: str | Path = "paper-fig3", overrides: list[str] | None = None, **fields: Any
) -> Scenario:
    """Load a preset or a YAML/TOML file, apply ``--set`` style overrides, and validate.

    Keyword ``fields`` set keys too, ``__`` standing for the dot
    (``load_scenario("paper-fig3", steps=5, control__solver="exact")``).

    A problem with a key an override set is named as the command line names it,
    ``--set antena.height=3: antena: unknown key (did you mean antenna?)``: the overrides are
    ``--set`` items, and one wording serves both (the tests and the README quote it).
    """
    overrides = override_items(overrides)
    return load_scenario_noted(name_or_path, overrides, **fields)[0]


def load_scenario_noted(
    name_or_path: str | Path = "paper-fig3", overrides: list[str] | None = None, **fields: Any
) -> tuple[Scenario, str | None]:
    """:func:`load_scenario`, and :func:`literal_note`'s warning for it (None when there is none),
    from the one reading of the file."""
    overrides = override_items(overrides)
    data, label, own = _scenario_source(name_or_path)
    data = apply_overrides(data, overrides)
    blame = overridden_keys(overrides)
    for key, value in fields.items():
        dotted = key.replace("__", ".")
        blame[dotted] = f"load_scenario({printable(shortened(f'{key}={_shown_value(value)}', SET_SHOWN))})"
        set_dotted(data, dotted, value, blame[dotted])
    s = validate_scenario(data, label, blame)
    return s, literal_note(own, label, overrides, s)


def scenario_to_dict(s: Scenario) -> dict:
    return s.model_dump(mode="json")


def scenario_to_yaml(s: Scenario) -> str:
    return yaml.dump(scenario_to_dict(s), Dumper=_Dumper, sort_keys=False, default_flow_style=None)
