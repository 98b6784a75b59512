"""app.runtime.disk: which filesystems readiness watches and when they count as full, and the database
errors that mean a full disk (a real SQLite one: a database capped at its current size by max_page_count)."""
from __future__ import annotations

import sqlite3

import psycopg
import pytest
from sqlalchemy.exc import OperationalError

from app.runtime.disk import free_mb, is_disk_full, storage_checks
from app.runtime.settings import Settings


def test_an_embedded_service_watches_its_database_and_data_directory(tmp_path):
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'db' / 'trajlab.db'}", data_dir=tmp_path,
                        broker_url="redis+socket:///x/redis.socket", min_free_disk_mb=0)
    (tmp_path / "db").mkdir()
    assert storage_checks(settings) == {"database_storage": "up", "data_dir": "up"}


def test_a_filesystem_with_less_than_the_setting_free_is_full(tmp_path):
    above = free_mb(tmp_path) + 1024  # more than the filesystem has left
    checks = storage_checks(Settings(database_url=f"sqlite:///{tmp_path / 'trajlab.db'}", data_dir=tmp_path,
                                     min_free_disk_mb=above))
    assert set(checks) == {"database_storage", "data_dir"}
    assert all(v.startswith("full: ") and "TRAJLAB_MIN_FREE_DISK_MB" in v for v in checks.values()), checks


def test_a_postgresql_service_without_a_data_directory_watches_nothing(tmp_path):
    settings = Settings(database_url="postgresql+psycopg://u@h/db", broker_url="redis://h:6379/0",
                        data_dir=tmp_path / "absent")
    assert storage_checks(settings) == {}


def _sqlite_full_error(tmp_path) -> sqlite3.Error:
    conn = sqlite3.connect(tmp_path / "capped.db")
    conn.execute("CREATE TABLE t (x BLOB)")
    conn.commit()
    pages = conn.execute("PRAGMA page_count").fetchone()[0]
    conn.execute(f"PRAGMA max_page_count = {pages}")  # no page more: the next growth is SQLITE_FULL
    try:
        with pytest.raises(sqlite3.OperationalError) as err:
            conn.execute("INSERT INTO t VALUES (zeroblob(100000))")
        return err.value
    finally:
        conn.close()


def test_sqlite_full_and_postgresql_disk_full_are_recognised(tmp_path):
    full = _sqlite_full_error(tmp_path)
    assert is_disk_full(full)
    assert is_disk_full(OperationalError("INSERT", {}, full))  # as SQLAlchemy raises it
    assert is_disk_full(OperationalError("INSERT", {}, psycopg.errors.DiskFull("could not extend file")))
    assert not is_disk_full(OperationalError("SELECT 1", {}, psycopg.errors.AdminShutdown("terminating")))
    assert not is_disk_full(OperationalError("SELECT 1", {}, sqlite3.OperationalError("database is locked")))
