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


def test_the_readmes_layout_names_every_module():
    readme = (SRC.parents[1] / "README.md").read_text()
    layout = readme.split("## Layout of the code", 1)[1]
    missing = []
    for package in sorted(p for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").exists()):
        row = next((line for line in layout.splitlines() if line.startswith(f"| `src/trackjam/{package.name}/`")), "")
        missing += [f"{package.name}/{m.name}" for m in sorted(package.glob("*.py"))
                    if m.name != "__init__.py" and f"`{m.name}`" not in row]
    assert not missing, f"README's layout does not name {missing}"
