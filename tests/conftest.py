"""Shared fixtures: an embedded SQLite database for unit tests."""
from __future__ import annotations

import pytest

from app.db import get_database
from app.migrate import upgrade


@pytest.fixture()
def sqlite_db(tmp_path):
    url = f"sqlite:///{tmp_path / 'trajlab.db'}"
    upgrade(url)
    db = get_database(url)
    yield db
    db.dispose()
