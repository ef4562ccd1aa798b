"""Shared test fixtures."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "chromium", "chromium-browser")


def _find_chromium() -> str | None:
    for name in CHROMIUM_CANDIDATES:
        found = name if os.path.isabs(name) and os.access(name, os.X_OK) else shutil.which(name)
        if found:
            return found
    return None


@pytest.fixture(scope="session")
def chromium_path() -> Path:
    """Path of a headless-capable Chromium, installed with apt (Debian package `chromium`) when
    missing. Fails, never skips: the replay's browser test is part of the suite."""
    found = _find_chromium()
    if found is None:
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        cmd = "apt-get update -qq && apt-get install -y -qq chromium"
        try:
            proc = subprocess.run(["sh", "-c", cmd], env=env, capture_output=True, text=True, timeout=900)
        except (OSError, subprocess.TimeoutExpired) as err:
            pytest.fail(f"Chromium is not installed and `{cmd}` could not run: {err}")
        found = _find_chromium()
        if proc.returncode != 0 or found is None:
            tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-15:])
            pytest.fail(
                f"Chromium is needed by the replay tests and is not installed; `{cmd}` failed "
                f"(exit {proc.returncode}; it needs root and the Debian archive). Last output:\n{tail}"
            )
    return Path(found)
