"""Where the tests find a headless Chromium or Chrome for the replay's browser tests.

The tests never install anything: they use ``TRACKJAM_BROWSER`` when it is set, else the first
of the usual names on PATH, else the macOS Chrome app. With none of them the browser tests
skip with the reason, unless ``TRACKJAM_REQUIRE_BROWSER=1`` (CI) turns the skip into a failure.
"""

from __future__ import annotations

import os
import shutil
from typing import Callable, Mapping

BROWSER_ENV = "TRACKJAM_BROWSER"
REQUIRE_ENV = "TRACKJAM_REQUIRE_BROWSER"
CANDIDATES = (
    "chromium",
    "chromium-browser",
    "google-chrome",
    "/Applications/Google Chrome.app/Contents/MacOS/Google Chrome",
)


class BrowserSetupError(Exception):
    """TRACKJAM_BROWSER names something that is not an executable: the user's mistake."""


def _executable(name: str, which: Callable[[str], str | None]) -> str | None:
    if os.path.isabs(name):
        return name if os.path.isfile(name) and os.access(name, os.X_OK) else None
    return which(name)


def find_browser(environ: Mapping[str, str] = os.environ, which: Callable[[str], str | None] = shutil.which,
                 candidates: tuple[str, ...] = CANDIDATES) -> str | None:
    """The browser's path, or None when there is none to find."""
    chosen = environ.get(BROWSER_ENV, "").strip()
    if chosen:
        found = _executable(chosen, which)
        if found is None:
            raise BrowserSetupError(f"{BROWSER_ENV}={chosen!r} is not an executable file or a command on PATH")
        return found
    for name in candidates:
        found = _executable(name, which)
        if found:
            return found
    return None


def missing_reason(candidates: tuple[str, ...] = CANDIDATES) -> str:
    return (f"no headless browser for the replay tests: set {BROWSER_ENV} or install one of "
            f"{', '.join(candidates[:3])} (or Google Chrome on macOS)")


def browser_required(environ: Mapping[str, str] = os.environ) -> bool:
    return environ.get(REQUIRE_ENV, "").strip() not in ("", "0")
