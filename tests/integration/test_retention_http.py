"""Issue 27 over HTTP against the real stack (PostgreSQL, Redis, the ``service`` fixture's worker):
results stored compressed and served unchanged, usage and the storage quota, DELETE of jobs and
studies with owner isolation, and migration 0006 on PostgreSQL with data in it.

The owners' app is built here with ``TRAJLAB_AUTH=required`` on the service's database and broker, so
its jobs run on the service's worker; keys are made with app.api.auth, owners are unique per run.
"""
from __future__ import annotations

import json
import time
import uuid
from pathlib import Path

import psycopg
import pytest
from alembic import command
from fastapi.testclient import TestClient
from sqlalchemy import select, text, update

from app.api import auth
from app.api.main import create_app
from app.api.routes import results as results_routes
from app.cli.client import Client, TrajlabError
from app.runtime import result_codec
from app.runtime.db import get_database, make_engine
from app.runtime.migrate import alembic_config, upgrade
from app.runtime.models import Job, StoredResult
from app.service import jobs, storage
from tests.integration.conftest import PG_ADMIN_URL

pytestmark = pytest.mark.integration

INTERCEPT = {"kind": "intercept", "preset": "long-range-intercept"}
QUICK = {"kind": "intercept", "preset": "long-range-intercept",
         "params": {"methods": ["impulsive"], "scan": {"step_s": 5.0}}}
# a midcourse NSGA-II run of minutes: caught running, then deleted
LONG = {"kind": "midcourse", "preset": "upper-stage-two-corrections",
        "params": {"mode": "optimize", "corrections": 2, "population": 100, "generations": 2500, "seed": 7}}


class Owners:
    def __init__(self, service):
        self.service = service
        self.db = service.client.app.state.db
        self.settings = service.settings.model_copy(update={"auth": "required"})
        self.client = TestClient(create_app(self.settings))
        run = uuid.uuid4().hex[:6]
        self.keys = {who: auth.create_key(self.db, name=f"{who}-{run}", admin=who == "ops")[1]
                     for who in ("alice", "bob", "carol", "ops")}

    def h(self, who: str) -> dict:
        return {"Authorization": f"Bearer {self.keys[who]}"}

    def wait(self, who: str, job_id: str, until=("succeeded", "failed", "cancelled"), timeout=240.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            job = self.client.get(f"/v1/jobs/{job_id}", headers=self.h(who)).json()
            if job["status"] in until and (job["status"] != "running" or job["progress"] > 0):
                return job
            assert time.monotonic() < deadline, f"job {job_id} still {job['status']} after {timeout} s"
            time.sleep(0.2)

    def worker_stopped(self, job_id: str, timeout: float = 60.0) -> None:
        """The worker's line for a delivery whose result was not stored (the job row is gone)."""
        deadline = time.monotonic() + timeout
        needle = f"job {job_id} attempt 1 refused"
        while time.monotonic() < deadline:
            if any(needle in p.read_text(errors="replace") for p in Path(self.service.log_dir).glob("worker-*.log")):
                return
            time.sleep(0.3)
        raise AssertionError(f"the worker never stopped job {job_id} (no '{needle}' in {self.service.log_dir})")


@pytest.fixture(scope="module")
def owners(service):
    o = Owners(service)
    yield o
    o.client.close()


def _rows(db, job_ids) -> tuple[int, int]:
    with db.read() as s:
        return (len(list(s.scalars(select(Job.id).where(Job.id.in_(job_ids))))),
                len(list(s.scalars(select(StoredResult.job_id).where(StoredResult.job_id.in_(job_ids))))))


def test_a_result_is_stored_compressed_served_unchanged_counted_and_deleted_whole(owners):
    c, db = owners.client, owners.db
    job = c.post("/v1/jobs", json=INTERCEPT, headers=owners.h("alice")).json()
    done = owners.wait("alice", job["id"])
    assert done["status"] == "succeeded", done
    jid = job["id"]

    # stored compressed, >= 5x under its JSON, and counted in jobs.stored_bytes
    with db.read() as s:
        row, stored = s.get(StoredResult, jid), s.get(Job, jid).stored_bytes
    assert row.encoding == result_codec.ENCODING and row.data is None
    doc = storage.read_result(row)
    json_bytes = len(json.dumps(doc, separators=(",", ":")))
    print(f"intercept preset: {json_bytes} bytes of JSON, {len(row.packed)} stored "
          f"({json_bytes / len(row.packed):.1f}x)")
    assert json_bytes >= 5 * len(row.packed)
    assert stored == storage.params_bytes(done["params"]) + len(row.packed)

    # the API's JSON is the same document byte for byte as from the uncompressed form
    views = ("", "?include=scan")
    served = {v: c.get(f"/v1/jobs/{jid}/result{v}", headers=owners.h("alice")).content for v in views}
    with db.write() as s:
        s.execute(update(StoredResult).where(StoredResult.job_id == jid).values(data=doc, packed=None, encoding=None))
    assert {v: c.get(f"/v1/jobs/{jid}/result{v}", headers=owners.h("alice")).content for v in views} == served
    with db.write() as s:
        storage.put_result(s, s.get(Job, jid), storage.pack(doc))

    # usage, and the storage quota: Alice is past a cap of half her bytes, Carol (nothing stored) is not
    usage = c.get("/v1/usage", headers=owners.h("alice")).json()
    assert (usage["jobs"], usage["jobs_by_status"], usage["stored_bytes"]) == (1, {"succeeded": 1}, stored)
    capped = TestClient(create_app(owners.settings.model_copy(
        update={"max_stored_mb_per_owner": stored / 2 / storage.MB})))
    refused = capped.post("/v1/jobs", json=INTERCEPT, headers=owners.h("alice"))
    assert refused.status_code == 429 and "TRAJLAB_MAX_STORED_MB_PER_OWNER" in refused.json()["detail"], refused.text
    admitted = capped.post("/v1/jobs", json=QUICK, headers=owners.h("carol"))
    assert admitted.status_code == 202, admitted.text
    capped.close()

    # renderings cached, then another owner's DELETE is a 404 that removes nothing
    assert c.get(f"/v1/jobs/{jid}/plots", headers=owners.h("alice")).status_code == 200
    assert c.get(f"/v1/jobs/{jid}/report.html", headers=owners.h("alice")).status_code == 200
    assert any(k[0] == jid for k in results_routes._CACHE)
    assert c.delete(f"/v1/jobs/{jid}", headers=owners.h("bob")).status_code == 404
    assert _rows(db, [jid]) == (1, 1)
    # the owner's DELETE removes the job, its result, its events and its cached renderings
    assert c.delete(f"/v1/jobs/{jid}", headers=owners.h("alice")).status_code == 204
    assert _rows(db, [jid]) == (0, 0)
    assert not any(k[0] == jid for k in results_routes._CACHE)
    for path in ("", "/result", "/events", "/plots", "/report.html"):
        assert c.get(f"/v1/jobs/{jid}{path}", headers=owners.h("alice")).status_code == 404, path
    assert c.delete(f"/v1/jobs/{jid}", headers=owners.h("alice")).status_code == 404
    assert c.get("/v1/usage", headers=owners.h("alice")).json()["stored_bytes"] == 0
    # an admin deletes any owner's job (Carol's, running or queued by now: cancelled first), here
    # through the Python client the CLI uses
    ops = Client(http=c, api_key=owners.keys["ops"])
    ops.delete(admitted.json()["id"])
    with pytest.raises(TrajlabError) as gone:
        Client(http=c, api_key=owners.keys["carol"]).job(admitted.json()["id"])
    assert gone.value.status_code == 404
    assert ops.usage()["owner"] is None  # an admin's usage counts every owner


def test_deleting_a_running_job_stops_it(owners):
    c = owners.client
    job = c.post("/v1/jobs", json=LONG, headers=owners.h("bob")).json()
    owners.wait("bob", job["id"], until=("running",), timeout=120)
    assert c.delete(f"/v1/jobs/{job['id']}", headers=owners.h("bob")).status_code == 204
    assert c.get(f"/v1/jobs/{job['id']}", headers=owners.h("bob")).status_code == 404
    owners.worker_stopped(job["id"])  # minutes of NSGA-II left: the solver stopped at its heartbeat
    assert _rows(owners.db, [job["id"]]) == (0, 0)  # and stored nothing


def test_deleting_a_study_deletes_its_points(owners):
    """Deleted while its points are queued or starting (a running job's deletion is the test above)."""
    c = owners.client
    body = {**LONG, "mode": "independent", "sweeps": [{"path": "seed", "values": [1, 2, 3]}]}
    study = c.post("/v1/studies", json=body, headers=owners.h("carol")).json()
    with owners.db.read() as s:
        points = list(s.scalars(select(Job.id).where(Job.study_id == study["id"])))
    assert len(points) == 3
    assert c.delete(f"/v1/studies/{study['id']}", headers=owners.h("bob")).status_code == 404
    point = c.delete(f"/v1/jobs/{points[0]}", headers=owners.h("carol"))  # a study goes whole
    assert point.status_code == 409 and f"DELETE /v1/studies/{study['id']}" in point.json()["detail"]
    assert _rows(owners.db, points)[0] == 3
    assert c.delete(f"/v1/studies/{study['id']}", headers=owners.h("carol")).status_code == 204
    assert c.get(f"/v1/studies/{study['id']}", headers=owners.h("carol")).status_code == 404
    assert _rows(owners.db, points) == (0, 0)


def test_migration_0006_on_postgresql_keeps_results_both_ways():
    admin = psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5)
    name = f"trajlab_m6_{uuid.uuid4().hex[:10]}"
    admin.execute(f'CREATE DATABASE "{name}"')
    url = PG_ADMIN_URL.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    engine = make_engine(url)
    try:
        cfg = alembic_config(url)
        command.upgrade(cfg, "0005")
        legacy = {"x": [0.5, 1.5], "n": 1}
        old_id = uuid.uuid4().hex
        with engine.begin() as conn:
            conn.execute(text("INSERT INTO jobs (id, kind, status, progress, message, params, created_at, attempts, "
                              "cancel_requested, queue) VALUES (:id, 'intercept', 'succeeded', 1.0, 'done', "
                              "CAST(:p AS json), now(), 1, false, 'trajlab.jobs')"), {"id": old_id, "p": '{"p": 1}'})
            conn.execute(text("INSERT INTO job_results (job_id, data, created_at) "
                              "VALUES (:id, CAST(:d AS json), now())"), {"id": old_id, "d": json.dumps(legacy)})
        upgrade(url)
        db = get_database(url)
        assert jobs.get_result(db, old_id) == legacy
        with db.read() as s:
            assert s.get(Job, old_id).stored_bytes == len('{"p": 1}') + len(json.dumps(legacy))
        new, _ = jobs.create_job(db, kind="intercept", params={"p": 2}, label=None, preset=None)
        jobs.claim(db, new.id, 1, worker="w", max_attempts=3, stale_after_s=60)
        result = {"x": [float(i) ** 1.5 for i in range(1000)]}
        assert jobs.finish(db, new.id, 1, status="succeeded", result=result, error=None, message="done")
        command.downgrade(cfg, "0005")
        with engine.connect() as conn:
            rows = dict(conn.execute(text("SELECT job_id, data FROM job_results")).all())
        assert rows == {old_id: legacy, new.id: result}
        upgrade(url)
        assert jobs.get_result(db, new.id) == result
        db.dispose()
    finally:
        engine.dispose()
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.close()
