"""Restores that trust nothing, on PostgreSQL (issue 36 item 4): a ``pg_dump`` of a trajlab database that also
carries a function, a trigger on ``jobs``, a view and an extra table is refused before anything is written
(the target's job stays, no object of the dump appears), naming what it found; the same database without
them restores.  Real PostgreSQL, databases of the test's own."""
from __future__ import annotations

import shutil
import subprocess
import uuid

import psycopg
import pytest

from app.cli.backup import BackupError, head_revision, restore
from app.runtime.db import get_database
from app.runtime.migrate import upgrade
from app.service import jobs
from tests.integration.conftest import PG_ADMIN_URL

pytestmark = pytest.mark.integration

HOSTILE = """
CREATE TABLE public.evil (job_id text);
CREATE FUNCTION public.spy() RETURNS trigger LANGUAGE plpgsql AS
  $$ BEGIN INSERT INTO public.evil VALUES (NEW.id); RETURN NEW; END $$;
CREATE TRIGGER jobs_spy AFTER INSERT ON public.jobs FOR EACH ROW EXECUTE FUNCTION public.spy();
CREATE VIEW public.every_key AS SELECT * FROM public.api_keys;
"""


@pytest.fixture()
def databases():
    admin = psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5)
    base = PG_ADMIN_URL.rsplit("/", 1)[0]
    names = [f"trajlab_rc_{role}_{uuid.uuid4().hex[:8]}" for role in ("source", "target")]
    for name in names:
        admin.execute(f'CREATE DATABASE "{name}"')
    yield [f"{base}/{n}".replace("postgresql://", "postgresql+psycopg://", 1) for n in names]
    for name in names:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
    admin.close()


def _libpq(url: str) -> str:
    return url.replace("postgresql+psycopg://", "postgresql://", 1)


def _dump(url: str, dest) -> None:
    subprocess.run([shutil.which("pg_dump"), "--format=custom", "--file", str(dest), "--dbname", _libpq(url)],
                   check=True, capture_output=True, timeout=120)


def test_a_hostile_dump_is_refused_before_a_byte_is_written_and_a_clean_one_restores(databases, tmp_path):
    source, target = databases
    for url in databases:
        upgrade(url)
    db = get_database(target)
    kept, _ = jobs.create_job(db, kind="intercept", params={"kept": True}, label=None, preset=None)
    db.dispose()
    src_db = get_database(source)
    restored_job, _ = jobs.create_job(src_db, kind="intercept", params={"from": "backup"}, label=None, preset=None)
    src_db.dispose()
    clean = tmp_path / "clean.dump"
    _dump(source, clean)
    with psycopg.connect(_libpq(source), autocommit=True) as conn:
        conn.execute(HOSTILE)
    hostile = tmp_path / "hostile.dump"
    _dump(source, hostile)

    with pytest.raises(BackupError) as refused:
        restore(target, hostile, force=True)
    message = str(refused.value)
    for named in ("TABLE public evil", "FUNCTION public spy()", "TRIGGER public jobs jobs_spy",
                  "VIEW public every_key"):
        assert named in message, message
    assert "\n" not in message and "nothing was written" in message
    with psycopg.connect(_libpq(target)) as conn:
        assert conn.execute("SELECT id FROM jobs").fetchall() == [(kept.id,)]
        assert conn.execute("SELECT to_regclass('public.evil'), to_regproc('public.spy')").fetchone() == (None, None)

    # a truncated archive: one line, the target as it was
    truncated = tmp_path / "truncated.dump"
    truncated.write_bytes(clean.read_bytes()[:200])
    with pytest.raises(BackupError, match="refused, nothing was written|pg_restore failed"):
        restore(target, truncated, force=True)
    with psycopg.connect(_libpq(target)) as conn:
        assert conn.execute("SELECT id FROM jobs").fetchall() == [(kept.id,)]

    # the dump made before the hostile objects restores (the check accepts what the migrations make)
    assert restore(target, clean, force=True)["revision"] == head_revision()
    with psycopg.connect(_libpq(target)) as conn:
        assert conn.execute("SELECT id FROM jobs").fetchall() == [(restored_job.id,)]
