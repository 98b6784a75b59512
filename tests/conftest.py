"""Shared fixtures: an embedded SQLite database for unit tests."""
from __future__ import annotations

import os

import pytest

# The service defaults to TRAJLAB_AUTH=required (production); the suite runs
# with auth off unless a test builds its app with auth required
# (tests/integration/test_security.py). Worker subprocesses inherit this too.
os.environ.setdefault("TRAJLAB_AUTH", "off")
# No C compiles in the suite's solves (solvers/transcription/jit.py: `trajlab serve` turns them on
# for its worker); tests/unit/test_jit.py sets the mode itself.
os.environ.setdefault("TRAJLAB_JIT", "off")

from app.db import get_database
from app.migrate import upgrade


@pytest.fixture()
def sqlite_db(tmp_path):
    url = f"sqlite:///{tmp_path / 'trajlab.db'}"
    upgrade(url)
    db = get_database(url)
    yield db
    db.dispose()
