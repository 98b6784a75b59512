"""Shared fixtures (an embedded SQLite database for unit tests) and the time each marker took."""
from __future__ import annotations

import os
import sys
import time
from collections import defaultdict

import pytest

# The service defaults to TRAJLAB_AUTH=required (production); the suite runs
# with auth off unless a test builds its app with auth required
# (tests/integration/test_security.py). Worker subprocesses inherit this too.
os.environ.setdefault("TRAJLAB_AUTH", "off")
# No C compiles in the suite's solves (solvers/transcription/jit.py: `trajlab serve` turns them on
# for its worker); tests/unit/test_jit.py sets the mode itself.
os.environ.setdefault("TRAJLAB_JIT", "off")
# Bytecode caches on for this process and every process it starts, also when pytest is run without the
# Makefile (which does the same): under PYTHONDONTWRITEBYTECODE each worker, recovery loop and CLI the
# suite starts compiles its imports from source (7.4 s of CPU against 3.0 s for the worker's imports).
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
sys.dont_write_bytecode = False

from app.runtime.db import get_database  # noqa: E402 (after the environment above)
from app.runtime.migrate import upgrade  # noqa: E402


@pytest.fixture()
def sqlite_db(tmp_path):
    url = f"sqlite:///{tmp_path / 'trajlab.db'}"
    upgrade(url)
    db = get_database(url)
    yield db
    db.dispose()


# ----------------------------------------------------------------------------- time per marker
# `make test` ends with where its minutes went.  A test counts under the first of these markers it
# carries (a slow browser test is a browser test), "unit" if none; setup and teardown included,
# so a session fixture's start-up (the integration service) counts where it is first used.
_CATEGORIES = ("faults", "browser", "slow", "integration")
_spent: dict[str, list[float]] = defaultdict(lambda: [0.0, 0])
_started = time.monotonic()


def _category(keywords) -> str:
    return next((c for c in _CATEGORIES if c in keywords), "unit")


def pytest_runtest_logreport(report):
    entry = _spent[_category(report.keywords)]
    entry[0] += report.duration
    if report.when == "call" or (report.when == "setup" and report.outcome != "passed"):
        entry[1] += 1


def pytest_terminal_summary(terminalreporter):
    if not _spent:
        return
    tr = terminalreporter
    tr.section("time per marker")
    for name in ("unit", "integration", "browser", "faults", "slow"):
        seconds, count = _spent.get(name, (0.0, 0))
        tr.write_line(f"{name:<12} {count:5d} tests {seconds:8.1f} s")
    tr.write_line(f"{'wall clock':<12} {'':11} {time.monotonic() - _started:8.1f} s")
