"""The model's packages take their own small parameters: only the build step, the command line,
the experiments and the public entry points read the configuration."""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "trackjam"
MODEL_PACKAGES = ("world", "radio", "estimation", "control", "metrics")


def imported_modules(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
    return out


@pytest.mark.parametrize("package", MODEL_PACKAGES)
def test_model_packages_never_import_the_configuration(package):
    offenders = [
        str(p.relative_to(SRC)) for p in sorted((SRC / package).rglob("*.py"))
        if any(m == "trackjam.config" or m.startswith("trackjam.config.") for m in imported_modules(p))
    ]
    assert not offenders
