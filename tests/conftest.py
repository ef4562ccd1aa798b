"""Shared test fixtures. Nothing here installs anything on the machine."""

from __future__ import annotations

from pathlib import Path

import pytest
from browser import BrowserSetupError, browser_required, find_browser, missing_reason


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
