"""What ``trajlab restore`` refuses before it touches a database: a file that is no backup, a backup of the
other kind of database, and (for ``backup``) writing over the database itself.  The round trips under
writes are tests/integration/test_backup_restore.py."""
from __future__ import annotations

import pytest

from app.cli.backup import BackupError, backup, file_kind, restore


def test_a_backup_says_which_database_it_holds(sqlite_db, tmp_path):
    copy = tmp_path / "copy.backup"
    done = backup(sqlite_db.url, copy)
    assert file_kind(copy) == "sqlite" and done["kind"] == "sqlite" and done["bytes"] == copy.stat().st_size
    assert not (tmp_path / "copy.backup.partial").exists()
    dump = tmp_path / "dump.backup"
    dump.write_bytes(b"PGDMP\x01\x0f\x00" + bytes(64))  # the first bytes of pg_dump's custom format
    assert file_kind(dump) == "postgresql"
    other = tmp_path / "notes.txt"
    other.write_text("not a backup")
    assert file_kind(other) is None
    with pytest.raises(BackupError, match="is not a trajlab backup"):
        restore(f"sqlite:///{tmp_path / 'new.db'}", other)


def test_a_backup_is_restored_only_into_its_own_kind_of_database(sqlite_db, tmp_path):
    copy = tmp_path / "copy.backup"
    backup(sqlite_db.url, copy)
    with pytest.raises(BackupError, match="holds a SQLite backup .* is PostgreSQL"):
        restore("postgresql+psycopg://nobody@127.0.0.1:1/none", copy)  # refused before any connection


def test_a_backup_never_overwrites_its_own_database(sqlite_db):
    path = sqlite_db.url.removeprefix("sqlite:///")
    with pytest.raises(BackupError, match="is the database itself"):
        backup(sqlite_db.url, path)


def test_a_restore_into_a_migrated_empty_database_needs_no_force(sqlite_db, tmp_path):
    from app.runtime.migrate import upgrade

    copy, target = tmp_path / "copy.backup", f"sqlite:///{tmp_path / 'target.db'}"
    backup(sqlite_db.url, copy)
    upgrade(target)  # the schema and its revision, no rows: empty
    assert restore(target, copy)["kind"] == "sqlite"
