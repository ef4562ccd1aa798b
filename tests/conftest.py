"""Shared test fixtures. Nothing here installs anything on the machine."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest
from browser import BrowserSetupError, browser_required, find_browser, missing_reason
from hypothesis import settings

# Property tests draw the same examples on every run (derandomize), so a test suite that passed
# passes again on the same code: CI does not fail on a rare example that one run happens to
# draw. TRACKJAM_HYPOTHESIS=explore draws fresh examples each run, to look for new failures.
settings.register_profile("repeatable", derandomize=True)
settings.register_profile("explore", derandomize=False)
_profile = os.environ.get("TRACKJAM_HYPOTHESIS", "repeatable")
if _profile not in ("repeatable", "explore"):
    raise pytest.UsageError(f"TRACKJAM_HYPOTHESIS: unknown profile {_profile!r}; use 'repeatable' (the default) or 'explore'")
settings.load_profile(_profile)

# The Ctrl-C tests need SIGINT delivered. A suite started in the background by a non-interactive
# shell (`pytest &`, nohup) inherits SIGINT ignored, and so would every `trackjam` it starts:
# they would run to the end instead of stopping. Python's own handler is what a terminal gives.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


MAX_WORKERS = 8  # the longest test file takes about 3 minutes; more workers only cost memory


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config):
    """`-n auto` (pyproject.toml): one pytest-xdist worker per core this process may run on, at
    most ``MAX_WORKERS``, so that a many-core machine does not start dozens of workers, each
    with its own numba, Dask and process pools. PYTEST_XDIST_AUTO_NUM_WORKERS, when set, is
    left to pytest-xdist."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(cores, MAX_WORKERS))


@pytest.fixture(scope="session")
def chromium_path() -> Path:
    """A headless-capable Chromium or Chrome (see tests/browser.py). Skips with the reason when
    there is none, fails instead when TRACKJAM_REQUIRE_BROWSER is set."""
    try:
        found = find_browser()
    except BrowserSetupError as err:
        pytest.fail(str(err))
    if found is None:
        if browser_required():
            pytest.fail(missing_reason() + " (TRACKJAM_REQUIRE_BROWSER is set)")
        pytest.skip(missing_reason())
    return Path(found)
