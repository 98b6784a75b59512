"""Migrations are safe on old data (issue 36 item 6): a database built at every earlier revision, holding
jobs, results, studies and API keys written by SQL valid at that revision, is upgraded to head on SQLite
and on PostgreSQL (a database of the test's own on the shared server), and every row is found again with
every value it was written with (in the columns that still exist), and each result reads back through the
service.  Before the fix, on SQLite, 0004's copy of ``jobs`` deleted every ``job_results`` row (foreign
keys on: dropping the old ``jobs`` cascaded).

The rows are made from the schema itself (reflected at that revision), so a column added by a later
migration needs no change here.
"""
from __future__ import annotations

import uuid
from datetime import UTC, datetime

import psycopg
import pytest
from alembic.script import ScriptDirectory
from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    DateTime,
    Float,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Text,
    create_engine,
    insert,
    select,
)

from app.runtime.db import get_database
from app.runtime.migrate import alembic_config, upgrade
from app.service import jobs
from tests.integration.conftest import PG_ADMIN_URL

pytestmark = pytest.mark.integration

EARLIER = [s.revision for s in reversed(list(ScriptDirectory.from_config(alembic_config("")).walk_revisions()))][:-1]
ROWS = 3   # of each table, per revision
WHEN = datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC)


def _value(column, i: int, table: str):
    t = column.type
    if column.name == "id" or (isinstance(t, String) and column.unique):
        return uuid.uuid4().hex
    if isinstance(t, Boolean):
        return bool(i % 2)
    if isinstance(t, (Integer, BigInteger)):
        return i + 1
    if isinstance(t, Float):
        return 0.5 + i
    if isinstance(t, DateTime):
        return WHEN
    if isinstance(t, JSON):
        return {"table": table, "row": i, "x": [1.5, 2.5]}
    if isinstance(t, LargeBinary):
        return bytes([i]) * 4
    if isinstance(t, (String, Text)):
        length = getattr(t, "length", None) or 64
        return f"{column.name[:4]}{i}"[:length]
    raise AssertionError(f"no value for {table}.{column.name} ({t!r})")


def _fill(url: str) -> dict[str, dict[str, dict]]:
    """Rows in every table of ours at the database's present revision: ``{table: {pk: row}}``."""
    engine = create_engine(url)
    meta = MetaData()
    meta.reflect(engine)
    written: dict[str, dict[str, dict]] = {}
    try:
        with engine.begin() as conn:
            for name in ("studies", "jobs", "job_results", "api_keys"):   # parents first
                if name not in meta.tables:
                    continue
                table, rows = meta.tables[name], {}
                for i in range(ROWS):
                    row = {c.name: _value(c, i, name) for c in table.columns}
                    if name == "jobs" and "studies" in written and "study_id" in row:
                        row["study_id"] = list(written["studies"])[i]
                    if name == "job_results":
                        row["job_id"] = list(written["jobs"])[i]
                        row["data"] = {"result_of": row["job_id"], "values": [i, i + 0.25]}
                        for blob in ("packed", "encoding"):   # a JSON row, as before compression
                            row.pop(blob, None)
                    conn.execute(insert(table).values(**row))
                    key = "job_id" if name == "job_results" else "id"
                    rows[row[key]] = row
                written[name] = rows
    finally:
        engine.dispose()
    return written


def _read(url: str) -> dict[str, dict[str, dict]]:
    engine = create_engine(url)
    meta = MetaData()
    meta.reflect(engine)
    try:
        with engine.connect() as conn:
            out = {}
            for name in ("studies", "jobs", "job_results", "api_keys"):
                key = "job_id" if name == "job_results" else "id"
                out[name] = {r[key]: dict(r) for r in conn.execute(select(meta.tables[name])).mappings()}
            return out
    finally:
        engine.dispose()


def _same(stored, written) -> bool:
    if isinstance(written, datetime) and isinstance(stored, datetime):
        return (stored if stored.tzinfo else stored.replace(tzinfo=UTC)) == written
    return stored == written


def _upgrade_and_find_every_row(url: str, revision: str) -> None:
    upgrade(url, revision)
    written = _fill(url)
    assert {"jobs", "job_results"} <= set(written)
    upgrade(url)
    found = _read(url)
    for table, rows in written.items():
        assert set(found[table]) >= set(rows), f"{table}: rows lost upgrading from {revision}"
        for key, row in rows.items():
            stored = found[table][key]
            changed = {c: (stored[c], v) for c, v in row.items() if c in stored and not _same(stored[c], v)}
            assert not changed, f"{table} {key} changed upgrading from {revision}: {changed}"
    db = get_database(url)
    try:
        for job_id, row in written["job_results"].items():
            assert jobs.get_result(db, job_id) == row["data"]   # as the service reads it
    finally:
        db.dispose()


@pytest.mark.parametrize("revision", EARLIER)
def test_every_row_survives_the_upgrade_from_each_revision_on_sqlite(revision, tmp_path):
    _upgrade_and_find_every_row(f"sqlite:///{tmp_path / 'old.db'}", revision)


@pytest.fixture()
def pg_database():
    admin = psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5)
    name = f"trajlab_mig_{uuid.uuid4().hex[:10]}"
    admin.execute(f'CREATE DATABASE "{name}"')
    yield PG_ADMIN_URL.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
    admin.close()


@pytest.mark.parametrize("revision", EARLIER)
def test_every_row_survives_the_upgrade_from_each_revision_on_postgresql(revision, pg_database):
    _upgrade_and_find_every_row(pg_database, revision)
