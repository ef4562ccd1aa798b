"""The README documents every configuration key, and CI runs the README's test command."""

from pathlib import Path
import typing

from pydantic import BaseModel

from trackjam.config import Scenario

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _keys(model: type[BaseModel], prefix: str = "") -> list[str]:
    out = []
    for name, field in model.model_fields.items():
        key = prefix + name
        out.append(key)
        for a in [field.annotation, *typing.get_args(field.annotation)]:
            if isinstance(a, type) and issubclass(a, BaseModel):
                out += _keys(a, key + ".")
    return out


def test_every_configuration_key_is_in_the_readme_with_a_description():
    missing = [k for k in _keys(Scenario) if f"| `{k}` |" not in README]
    assert not missing, f"README lacks: {missing}"


def test_ci_runs_the_readmes_test_command_exactly():
    first_block = README.split("```bash", 1)[1].split("```", 1)[0].strip().splitlines()
    assert len(first_block) == 2  # exactly two set-up commands open the README
    install_run, install_test = first_block
    assert "trackjam run" in install_run and "pytest" in install_test
    assert install_test in (ROOT / ".ci" / "run").read_text().splitlines()
