"""Refactoring the step leaves every logged value of a seeded run unchanged, bit for bit.

The golden logs were recorded by ``golden.py --record``; a change that alters the model's
behaviour on purpose re-records them in its own commit and says so.
"""

import numpy as np
import pytest

from golden import CASES, path, run_case


@pytest.mark.parametrize("name", sorted(CASES))
def test_run_reproduces_its_recorded_logs(name):
    recorded = np.load(path(name))
    now = run_case(name)
    missing = sorted(set(recorded.files) - set(now))
    assert not missing, f"columns no longer logged: {missing}"
    changed = [
        k for k in recorded.files
        if recorded[k].shape != now[k].shape
        or not np.array_equal(recorded[k], now[k], equal_nan=recorded[k].dtype.kind == "f")
    ]
    assert not changed, (
        f"{name}: {changed} differ from the recorded run; if the behaviour changed on purpose, "
        "re-record with `python tests/simulation/golden.py --record`"
    )
