"""The tests find a browser without installing one, and CI installs Debian's chromium itself."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from browser import CANDIDATES, BrowserSetupError, browser_required, find_browser

ROOT = Path(__file__).resolve().parents[1]


def _script(path: Path) -> Path:
    path.write_text("#!/bin/sh\nexit 0\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


def test_the_environment_variable_comes_first(tmp_path):
    mine = _script(tmp_path / "my-chrome")
    assert find_browser({"TRACKJAM_BROWSER": str(mine)}, which=lambda n: f"/usr/bin/{n}") == str(mine)


def test_a_browser_variable_naming_nothing_is_an_error_not_a_silent_fallback(tmp_path):
    with pytest.raises(BrowserSetupError, match="TRACKJAM_BROWSER='/nowhere/chrome' is not an executable"):
        find_browser({"TRACKJAM_BROWSER": "/nowhere/chrome"}, which=lambda n: f"/usr/bin/{n}")
    plain = tmp_path / "not-executable"
    plain.write_text("")
    with pytest.raises(BrowserSetupError):
        find_browser({"TRACKJAM_BROWSER": str(plain)}, which=lambda n: None)


def test_the_names_are_tried_in_order_and_none_found_is_none(tmp_path):
    on_path = {"chromium-browser": "/opt/cb", "google-chrome": "/opt/gc"}
    assert find_browser({}, which=on_path.get) == "/opt/cb"
    assert find_browser({}, which={"google-chrome": "/opt/gc"}.get) == "/opt/gc"
    assert find_browser({}, which=lambda n: None, candidates=CANDIDATES[:3]) is None
    mac = _script(tmp_path / "Google Chrome")
    assert find_browser({}, which=lambda n: None, candidates=(*CANDIDATES[:3], str(mac))) == str(mac)


def test_requiring_a_browser_is_opt_in():
    assert not browser_required({}) and not browser_required({"TRACKJAM_REQUIRE_BROWSER": "0"})
    assert browser_required({"TRACKJAM_REQUIRE_BROWSER": "1"})


# The two tests below read files as text and run nothing: the package managers' names are what
# they look for (in the other tests, which must not name them) and what .ci/run, which CI runs
# as root, must call before the test command.
INSTALLERS = ("apt-get", "brew install")


def _names_an_installer(path: Path) -> bool:
    text = path.read_text()  # once per file (it was read twice)
    return any(word in text for word in INSTALLERS)


def test_no_test_installs_system_packages():
    offenders = [p.relative_to(ROOT) for p in (ROOT / "tests").rglob("*.py")
                 if p.name != "test_browser.py" and _names_an_installer(p)]
    assert not offenders


def test_ci_installs_chromium_before_the_test_command_and_requires_it():
    lines = (ROOT / ".ci" / "run").read_text().splitlines()
    test_line = next(i for i, line in enumerate(lines) if "-m pytest" in line)
    install = next(i for i, line in enumerate(lines) if f"{INSTALLERS[0]} install" in line and "chromium" in line)
    require = next(i for i, line in enumerate(lines) if "TRACKJAM_REQUIRE_BROWSER=1" in line)
    assert install < test_line and require < test_line
    assert os.access(ROOT / ".ci" / "run", os.X_OK)
