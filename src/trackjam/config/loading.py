"""Reading a scenario: a YAML or TOML file or a built-in preset, amended with dotted
``key=value`` overrides; every path ends in :func:`validate_scenario`, so all fail alike, with one
line naming the key and the problem."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from trackjam.config.model import Scenario
from trackjam.errors import ConfigError

def _format_error(err: ValidationError) -> str:
    parts = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"] if not str(p).startswith("function-"))
        msg = e["msg"]
        if e["type"] == "extra_forbidden":
            msg = "unknown key"
        msg = msg.removeprefix("Value error, ")
        parts.append(f"{loc}: {msg}" if loc else msg)
    return "; ".join(parts)


def validate_scenario(data: Any, source: str = "scenario") -> Scenario:
    """Validate a mapping as a :class:`Scenario`, raising :class:`ConfigError` with one line."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: the scenario must be a mapping of keys, got {type(data).__name__}")
    try:
        return Scenario.model_validate(data)
    except ValidationError as err:
        raise ConfigError(f"{source}: {_format_error(err)}") from None


def preset_names() -> list[str]:
    files = resources.files("trackjam.presets")
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml"))


def _preset_data(name: str) -> dict:
    return yaml.safe_load(resources.files("trackjam.presets").joinpath(f"{name}.yaml").read_text())


def _read_file(path: Path) -> dict:
    if not path.exists():
        raise ConfigError(f"{path}: no such file (and no preset of that name; see `trackjam presets`)")
    if path.is_dir():
        raise ConfigError(f"{path}: is a folder, not a scenario file")
    text = path.read_text()
    try:
        if path.suffix.lower() == ".toml":
            data = tomllib.loads(text)
        else:
            data = yaml.safe_load(text)
    except (yaml.YAMLError, tomllib.TOMLDecodeError) as err:
        first = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ConfigError(f"{path}: not valid {'TOML' if path.suffix.lower() == '.toml' else 'YAML'}: {first}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: the scenario must be a mapping of keys")
    return data


def _parse_value(text: str) -> Any:
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def set_dotted(data: dict, key: str, value: Any) -> None:
    """Set ``data[a][b][c] = value`` for ``key = "a.b.c"``, creating sections as needed."""
    parts = key.strip().split(".")
    if not all(parts):
        raise ConfigError(f"--set {key!r}: empty key")
    node = data
    for p in parts[:-1]:
        nxt = node.get(p)
        if nxt is None:
            nxt = {}
            node[p] = nxt
        if not isinstance(nxt, dict):
            raise ConfigError(f"--set {key}: {p} is not a section")
        node = nxt
    node[parts[-1]] = value


def apply_overrides(data: dict, overrides: list[str] | None) -> dict:
    """Apply dotted ``key=value`` overrides (values parsed as YAML) to a copy of a mapping."""
    data = _deep_copy(data)
    for item in overrides or []:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected key=value")
        key, _, value = item.partition("=")
        set_dotted(data, key, _parse_value(value))
    return data


def _deep_copy(d: Any) -> Any:
    if isinstance(d, dict):
        return {k: _deep_copy(v) for k, v in d.items()}
    if isinstance(d, list):
        return [_deep_copy(v) for v in d]
    return d


def load_scenario_data(name_or_path: str | Path) -> tuple[dict, str]:
    """Raw mapping of a preset name or a file, and a label for messages."""
    text = str(name_or_path)
    if isinstance(name_or_path, str) and text in preset_names():
        return _preset_data(text), f"preset {text}"
    return _read_file(Path(text)), text


def load_scenario(
    name_or_path: str | Path = "paper-fig3", overrides: list[str] | None = None, **fields: Any
) -> Scenario:
    """Load a preset or a YAML/TOML file, apply ``--set`` style overrides, and validate.

    Keyword ``fields`` set keys too, ``__`` standing for the dot
    (``load_scenario("paper-fig3", steps=5, control__solver="exact")``).
    """
    data, label = load_scenario_data(name_or_path)
    data = apply_overrides(data, overrides)
    for key, value in fields.items():
        set_dotted(data, key.replace("__", "."), value)
    return validate_scenario(data, label)


def scenario_to_dict(s: Scenario) -> dict:
    return s.model_dump(mode="json")


def scenario_to_yaml(s: Scenario) -> str:
    return yaml.safe_dump(scenario_to_dict(s), sort_keys=False, default_flow_style=None)
