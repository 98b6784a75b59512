"""``trajlab backup`` while jobs are being submitted and finished, ``trajlab restore`` into an empty database,
on SQLite and on PostgreSQL: every job and result that existed when the backup began is restored as it was,
nothing half-written comes back, and a database that holds rows is not overwritten without ``--force``.

Each run has a database, a Redis database and a real worker of its own (a shared worker would store these
jobs in another test's database); the backup and the restore run as the operator runs them, as commands.
"""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import psycopg
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import MetaData, create_engine, select

from app.api.main import create_app
from app.cli.backup import BackupError, restore
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings
from app.service.broker import QUEUES
from tests.integration.conftest import PG_ADMIN_URL, REDIS_URL, claim_redis_db
from tests.integration.live import stop_group

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parents[2]
QUICK = {"kind": "intercept", "preset": "long-range-intercept",
         "params": {"methods": ["impulsive"], "scan": {"step_s": 20.0}}}
FINAL = ("succeeded", "failed", "cancelled")


def _trajlab(url: str, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "TRAJLAB_DATABASE_URL": url, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "app.cli.commands", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=120)


class Databases:
    """A source and an empty target database of one kind, dropped afterwards."""

    def __init__(self, kind: str, tmp: Path):
        self.kind, self._names = kind, []
        if kind == "sqlite":
            self.source, self.target = f"sqlite:///{tmp / 'source.db'}", f"sqlite:///{tmp / 'restored' / 'trajlab.db'}"
            return
        self._admin = psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5)
        base = PG_ADMIN_URL.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1)
        urls = []
        for role in ("source", "target"):
            name = f"trajlab_bk_{role}_{uuid.uuid4().hex[:8]}"
            self._admin.execute(f'CREATE DATABASE "{name}"')
            self._names.append(name)
            urls.append(f"{base}/{name}")
        self.source, self.target = urls

    def drop(self) -> None:
        for name in self._names:
            self._admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        if self._names:
            self._admin.close()


def _rows(url: str) -> dict[str, dict[tuple, dict]]:
    """Every row of every table, by primary key (the tables as the database has them, not as the models say)."""
    engine = create_engine(url)
    try:
        meta = MetaData()
        meta.reflect(engine)
        out = {}
        with engine.connect() as conn:
            for name, table in meta.tables.items():
                key = [c.name for c in table.primary_key.columns] or [c.name for c in table.columns]
                out[name] = {tuple(r[k] for k in key): dict(r) for r in conn.execute(select(table)).mappings()}
        return out
    finally:
        engine.dispose()


class Submitter(threading.Thread):
    """Submits quick jobs one after another until stopped; when each request was sent and answered."""

    def __init__(self, client: TestClient):
        super().__init__(daemon=True)
        self.client, self.accepted, self.refused = client, [], []
        self._halt = threading.Event()

    def run(self) -> None:
        while not self._halt.wait(0.1):  # about what one worker finishes
            sent = time.monotonic()
            r = self.client.post("/v1/jobs", json=QUICK)
            (self.accepted.append((sent, time.monotonic(), r.json()["id"])) if r.status_code == 202
             else self.refused.append(r.status_code))

    def stop(self) -> None:
        self._halt.set()
        self.join(timeout=30)


@pytest.mark.parametrize("kind", ["sqlite", "postgresql"])
def test_backup_under_writes_restores_every_job_and_result(kind, tmp_path):
    dbs = Databases(kind, tmp_path)
    r, redis_url = claim_redis_db(REDIS_URL)
    worker = client = submitter = None
    try:
        t0 = time.monotonic()
        upgrade(dbs.source)
        overrides = {"TRAJLAB_DATABASE_URL": dbs.source, "TRAJLAB_BROKER_URL": redis_url,
                     "TRAJLAB_HEARTBEAT_INTERVAL_S": "0.5"}
        env = {**os.environ, **overrides, "PYTHONPATH": str(ROOT)}
        worker = subprocess.Popen(
            [sys.executable, "-m", "celery", "-A", "worker.celery_app:celery_app", "worker", "--loglevel=INFO",
             "--concurrency=1", "-n", f"backup-{uuid.uuid4().hex[:6]}@%h", "-Q", ",".join(QUEUES)],
            cwd=ROOT, env=env, stdout=open(tmp_path / "worker.log", "wb"), stderr=subprocess.STDOUT,
            start_new_session=True)
        client = TestClient(create_app(Settings(**{k.removeprefix("TRAJLAB_").lower(): v
                                                   for k, v in overrides.items()})))
        first = client.post("/v1/jobs", json=QUICK).json()["id"]  # the worker is up once it has run one
        deadline = time.monotonic() + 180
        while client.get(f"/v1/jobs/{first}").json()["status"] not in FINAL:
            assert time.monotonic() < deadline, f"the worker ran no job in 180 s; its log is in {tmp_path}"
            time.sleep(0.2)
        submitter = Submitter(client)
        submitter.start()
        while sum(j["status"] in FINAL for j in client.get("/v1/jobs", params={"limit": 100}).json()["items"]) < 6:
            assert time.monotonic() < deadline, f"the worker finished too few jobs in 180 s; its log is in {tmp_path}"
            time.sleep(0.2)

        t_first = time.monotonic()
        before = _rows(dbs.source)  # read just before the backup: every row here existed when it began
        began = time.monotonic()
        done = _trajlab(dbs.source, "backup", str(tmp_path / "trajlab.backup"))
        ended = time.monotonic()
        submitter.stop()
        assert done.returncode == 0, done.stderr
        # a submission whose request overlapped the backup: a write on SQLite may wait for the backup's lock
        # and be answered after the command ended (it was still sent, and written, while the backup ran)
        during = [i for sent, answered, i in submitter.accepted if sent <= ended and answered >= began]
        assert during, "no job was submitted while the backup ran"
        assert submitter.refused == []

        t_restore = time.monotonic()
        restored = _trajlab(dbs.target, "restore", str(tmp_path / "trajlab.backup"))
        assert restored.returncode == 0, restored.stderr
        t_restore = time.monotonic() - t_restore
        after, now = _rows(dbs.target), _rows(dbs.source)

        assert set(after) == set(now)  # every table, alembic's revision included
        assert after["alembic_version"] == now["alembic_version"]
        jobs, results = after["jobs"], after["job_results"]
        # every job and result of before the backup is there; every job restored was one of the source's
        assert set(before["jobs"]) <= set(jobs) <= set(now["jobs"])
        assert set(before["job_results"]) <= set(results)
        finished_before = [k for k, row in before["jobs"].items() if row["status"] in FINAL]
        assert len(finished_before) >= 5
        for key in finished_before:  # a finished job never changes again: restored exactly as it is
            assert jobs[key] == now["jobs"][key]
        for key, row in results.items():  # results are written once, with the job's final status
            assert row == now["job_results"][key]
        # no partial rows: a job restored as succeeded has its result, one restored unfinished has none
        assert all(k in results for k, row in jobs.items() if row["status"] == "succeeded")
        assert all(jobs[k]["status"] in FINAL for k in results)
        for key, row in jobs.items():  # what a job was submitted with is what the source holds
            assert {c: row[c] for c in ("kind", "params", "owner", "created_at", "queue")} == \
                   {c: now["jobs"][key][c] for c in ("kind", "params", "owner", "created_at", "queue")}
        print(f"\nBACKUP {kind}: {len(jobs)} jobs ({sum(k in results for k in jobs)} with results) in the backup, "
              f"{len(during)} submitted while it ran; first 5 finished after {t_first - t0:.1f} s, "
              f"backup {ended - began:.1f} s, restore {t_restore:.1f} s (commands with their start-up)")

        # the restored database serves them: one result through the API, as stored in the source
        key = next(k for k in finished_before if before["jobs"][k]["status"] == "succeeded")
        with TestClient(create_app(Settings(database_url=dbs.target, broker_url=redis_url))) as restored_api:
            url = f"/v1/jobs/{key[0]}/result"
            assert restored_api.get(url).json() == client.get(url).json()
            restored_api.app.state.db.dispose()

        with pytest.raises(BackupError, match=r"not empty .*--force"):  # in process: the command's message
            restore(dbs.target, tmp_path / "trajlab.backup")
        assert _rows(dbs.target)["jobs"] == jobs
    finally:
        if submitter is not None:
            submitter.stop()
        if client is not None:
            client.close()
            client.app.state.db.dispose()
        stop_group(worker)
        r.flushdb()
        dbs.drop()
