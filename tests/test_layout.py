"""Only the build step, the command line and the experiments read the configuration: every other
module takes its own small parameters (``simulation/build.py`` makes them from the scenario), and
a module that is handed a scenario only passes it on to build."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "trackjam"
MODEL_PACKAGES = ("world", "radio", "estimation", "control", "metrics")
# Where the configuration may be imported, relative to src/trackjam ("/" ends a package).
READERS = ("config/", "simulation/build.py", "cli.py", "__main__.py", "experiments/")
CONFIG = "trackjam.config"


def _absolute(module: str | None, level: int, package: str) -> str:
    """The absolute name of ``from <level dots><module> import ...`` written in ``package``."""
    if not level:
        return module or ""
    base = package.split(".")[: len(package.split(".")) - level + 1]
    return ".".join(base + ([module] if module else []))


def _is_config(name: str) -> bool:
    return name == CONFIG or name.startswith(CONFIG + ".")


def _type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def config_imports(source: str, module: str) -> list[tuple[int, bool]]:
    """``(line, type_only)`` of each import of the configuration in ``source``, the text of the
    module named ``module``: ``import``/``from`` at module level or inside a function, absolute or
    relative, ``from trackjam import config``, and ``importlib.import_module``/``__import__``
    with a literal name. ``type_only``: in the body of an ``if TYPE_CHECKING:`` (never run)."""
    is_package = module.endswith(".__init__")
    package = module.removesuffix(".__init__") if is_package else module.rpartition(".")[0]
    found = []

    def visit(node: ast.AST, type_only: bool) -> None:
        if isinstance(node, ast.If) and _type_checking(node.test):
            for child in node.body:
                visit(child, True)
            for child in node.orelse:
                visit(child, type_only)
            return
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(node.module, node.level, package)
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if called in ("import_module", "__import__") and isinstance(node.args[0].value, str):
                names = [node.args[0].value]
        if any(_is_config(n) for n in names):
            found.append((node.lineno, type_only))
        for child in ast.iter_child_nodes(node):
            visit(child, type_only)

    visit(ast.parse(source), False)
    return found


def _modules():
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        yield rel, "trackjam." + rel.removesuffix(".py").replace("/", "."), path.read_text()


def _reads_config(rel: str) -> bool:
    return any(rel.startswith(r) if r.endswith("/") else rel == r for r in READERS)


def test_the_allowed_readers_exist():
    for r in READERS:
        assert (SRC / r).exists(), r


def test_only_the_build_step_the_cli_and_the_experiments_import_the_configuration():
    """Not even for types: the entry points that are handed a scenario to pass on to build
    (``Simulation``, ``simulate``, ``parallel_env``, ``write_run``) name its type through
    ``trackjam.simulation.build``."""
    offenders = [
        f"{rel}:{line}" for rel, module, text in _modules() if not _reads_config(rel)
        for line, _ in config_imports(text, module)
    ]
    assert not offenders, f"these modules import trackjam.config outside build/cli/experiments: {offenders}"


@pytest.mark.parametrize("package", MODEL_PACKAGES)
def test_model_packages_never_import_the_configuration_not_even_for_types(package):
    offenders = [
        f"{rel}:{line}" for rel, module, text in _modules() if rel.startswith(package + "/")
        for line, _ in config_imports(text, module)
    ]
    assert not offenders


@pytest.mark.parametrize(
    "module, source, expected",
    [
        ("trackjam.viz.figure", "from trackjam.config import Scenario", [(1, False)]),
        ("trackjam.viz.figure", "import trackjam.config.loading as l", [(1, False)]),
        ("trackjam.viz.figure", "def f():\n    from trackjam.config.loading import load_scenario", [(2, False)]),
        ("trackjam.viz.figure", "from ..config import Scenario", [(1, False)]),
        ("trackjam.viz.figure", "from .. import config", [(1, False)]),
        ("trackjam.viz.__init__", "from ..config.model import Scenario", [(1, False)]),
        ("trackjam.__init__", "from .config import load_scenario", [(1, False)]),
        ("trackjam.__init__", "from . import config", [(1, False)]),
        ("trackjam.viz.figure", "from trackjam import config", [(1, False)]),
        ("trackjam.viz.figure", "import importlib\nimportlib.import_module('trackjam.config')", [(2, False)]),
        ("trackjam.viz.figure", "__import__('trackjam.config.model')", [(1, False)]),
        ("trackjam.viz.figure", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from trackjam.config import Scenario",
         [(3, True)]),
        ("trackjam.viz.figure", "import typing\nif typing.TYPE_CHECKING:\n    pass\nelse:\n    import trackjam.config",
         [(5, False)]),
        ("trackjam.viz.figure", "from trackjam.configuration import x\nfrom .config import y\nimport trackjam.viz", []),
        ("trackjam.viz.figure", "from trackjam.simulation.build import figure_settings", []),
    ],
)
def test_the_check_finds_every_way_of_importing_the_configuration(module, source, expected):
    assert config_imports(source, module) == expected


def test_importing_the_package_does_not_load_the_configuration():
    code = "import sys, trackjam; print(sorted(m for m in sys.modules if m.startswith('trackjam.')))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_the_readmes_layout_names_every_module():
    readme = (SRC.parents[1] / "README.md").read_text()
    layout = readme.split("## Layout of the code", 1)[1]
    missing = []
    for package in sorted(p for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").exists()):
        row = next((line for line in layout.splitlines() if line.startswith(f"| `src/trackjam/{package.name}/`")), "")
        missing += [f"{package.name}/{m.name}" for m in sorted(package.glob("*.py"))
                    if m.name != "__init__.py" and f"`{m.name}`" not in row]
    assert not missing, f"README's layout does not name {missing}"
