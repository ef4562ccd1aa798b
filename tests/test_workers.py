"""The suite's worker count under `-n auto` (tests/conftest.py)."""

import os
from pathlib import Path

import pytest


@pytest.fixture
def conftest(pytestconfig):
    """tests/conftest.py as pytest loaded it (`import conftest` may give another folder's)."""
    path = Path(__file__).with_name("conftest.py").resolve()
    found = [p for p in pytestconfig.pluginmanager.get_plugins()
             if getattr(p, "__file__", None) and Path(p.__file__).resolve() == path]
    assert len(found) == 1, found
    return found[0]


def test_auto_gives_one_worker_per_available_core_capped(conftest, monkeypatch):
    monkeypatch.delenv("PYTEST_XDIST_AUTO_NUM_WORKERS", raising=False)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(64)), raising=False)
    assert conftest.pytest_xdist_auto_num_workers(None) == conftest.MAX_WORKERS
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    assert conftest.pytest_xdist_auto_num_workers(None) == 2
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(), raising=False)
    assert conftest.pytest_xdist_auto_num_workers(None) == 1


def test_the_environment_variable_is_left_to_pytest_xdist(conftest, monkeypatch):
    monkeypatch.setenv("PYTEST_XDIST_AUTO_NUM_WORKERS", "3")
    assert conftest.pytest_xdist_auto_num_workers(None) is None
