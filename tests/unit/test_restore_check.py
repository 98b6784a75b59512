"""Restores that trust nothing, on SQLite (issue 36 item 4): a backup carrying a table and a trigger the
migrations never made, or a damaged file, is refused in one line and the target is left byte for byte as it
was (or not created); a backup at an earlier revision, made by the migrations, is restored.  The same for a
PostgreSQL dump: tests/integration/test_restore_check_pg.py."""
from __future__ import annotations

import hashlib
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from app.cli.backup import BackupError, backup, restore
from app.runtime.migrate import upgrade
from app.runtime.restore_check import UnsafeBackup, check_sqlite
from app.service import jobs

ROOT = Path(__file__).resolve().parents[2]


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture()
def target(tmp_path):
    """A service database holding one job: what a refused restore must leave alone."""
    from app.runtime.db import get_database

    url = f"sqlite:///{tmp_path / 'target' / 'trajlab.db'}"
    upgrade(url)
    db = get_database(url)
    jobs.create_job(db, kind="intercept", params={"kept": True}, label=None, preset=None)
    db.dispose()
    path = Path(url.removeprefix("sqlite:///"))
    for suffix in ("-wal", "-shm"):   # one file, so its bytes are the whole database
        Path(str(path) + suffix).unlink(missing_ok=True)
    return url, path


def _hostile(sqlite_db, tmp_path) -> Path:
    copy = tmp_path / "hostile.backup"
    backup(sqlite_db.url, copy)
    with sqlite3.connect(copy) as conn:
        conn.execute("CREATE TABLE evil (job_id TEXT)")
        conn.execute("CREATE TRIGGER jobs_spy AFTER INSERT ON jobs BEGIN INSERT INTO evil VALUES (new.id); END")
    conn.close()
    return copy


def test_a_backup_with_an_extra_table_and_a_trigger_is_refused_and_the_target_untouched(sqlite_db, tmp_path, target):
    url, path = target
    before = _digest(path)
    copy = _hostile(sqlite_db, tmp_path)
    with pytest.raises(BackupError) as refused:
        restore(url, copy, force=True)
    message = str(refused.value)
    assert "table evil" in message and "trigger jobs_spy" in message and "nothing was written" in message
    assert "\n" not in message
    assert _digest(path) == before
    # into a database that does not exist yet: not even created
    fresh = tmp_path / "fresh" / "trajlab.db"
    with pytest.raises(BackupError, match="trigger jobs_spy"):
        restore(f"sqlite:///{fresh}", copy)
    assert not fresh.exists()


def test_a_changed_definition_is_refused(sqlite_db, tmp_path):
    copy = tmp_path / "changed.backup"
    backup(sqlite_db.url, copy)
    with sqlite3.connect(copy) as conn:   # same name, another definition: an index on another column
        conn.execute("DROP INDEX ix_jobs_created_at")
        conn.execute("CREATE INDEX ix_jobs_created_at ON jobs (params)")
    conn.close()
    with pytest.raises(UnsafeBackup, match="defined otherwise: index ix_jobs_created_at"):
        check_sqlite(copy)


def test_a_damaged_file_is_one_line_from_the_command_and_the_target_untouched(sqlite_db, tmp_path, target):
    url, path = target
    before = _digest(path)
    copy = tmp_path / "damaged.backup"
    backup(sqlite_db.url, copy)
    data = bytearray(copy.read_bytes())
    page = 4096
    data[page:3 * page] = os.urandom(2 * page)   # the header stays: it still says SQLite
    copy.write_bytes(bytes(data))
    env = {**os.environ, "TRAJLAB_DATABASE_URL": url, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "app.cli.commands", "restore", str(copy), "--force"], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 1, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("trajlab restore: "), done.stderr
    assert "Traceback" not in done.stderr and "refused, nothing was written" in lines[0]
    assert _digest(path) == before


def test_a_backup_at_an_earlier_revision_is_checked_against_that_revision(tmp_path):
    old = f"sqlite:///{tmp_path / 'old.db'}"
    upgrade(old, "0003")
    copy = tmp_path / "old.backup"
    backup(old, copy)
    assert check_sqlite(copy) == "0003"
    restored = restore(f"sqlite:///{tmp_path / 'restored.db'}", copy)
    assert restored["revision"] == "0003"
    # a revision this version does not have is refused (a newer trajlab's backup)
    with sqlite3.connect(copy) as conn:
        conn.execute("UPDATE alembic_version SET version_num = '9999'")
    conn.close()
    with pytest.raises(UnsafeBackup, match="revision '9999'"):
        check_sqlite(copy)
