"""Refactoring the step leaves every logged value of a seeded run unchanged.

Discrete columns (moves, levels, modes, flags) must match exactly. Floating-point columns must
match to a relative 1e-5: on one machine they are bit for bit, but another build of numpy,
numba or LLVM, or another CPU, changes the last digits (up to 2e-6 relative was seen between two
machines with the same code). A change of behaviour moves a seeded run by far more than that.

The golden logs were recorded by ``golden.py --record``; a change that alters the model's
behaviour on purpose re-records them in its own commit and says so.
"""

import numpy as np
import pytest

from golden import CASES, path, run_case


def same(a: np.ndarray, b: np.ndarray) -> bool:
    if a.dtype.kind == "f":
        return bool(np.allclose(a, b, rtol=1e-5, atol=1e-8, equal_nan=True))
    return bool(np.array_equal(a, b))


def test_same_tells_a_changed_value_from_a_rounding():
    a = np.array([1.0, np.nan, 50.0])
    assert same(a, a * (1 + 2e-6))
    assert not same(a, a + np.array([0.0, 0.0, 0.01]))
    assert not same(np.array([1, 2]), np.array([1, 3]))


@pytest.mark.parametrize("name", sorted(CASES))
def test_run_reproduces_its_recorded_logs(name):
    recorded = np.load(path(name))
    now = run_case(name)
    missing = sorted(set(recorded.files) - set(now))
    assert not missing, f"columns no longer logged: {missing}"
    changed = [
        k for k in recorded.files
        if recorded[k].shape != now[k].shape
        or not same(recorded[k], now[k])
    ]
    assert not changed, (
        f"{name}: {changed} differ from the recorded run; if the behaviour changed on purpose, "
        "re-record with `python tests/simulation/golden.py --record`"
    )
