"""Issue 11 over HTTP against the real stack: PostgreSQL, Redis and real Celery workers.

The app is built here with ``TRAJLAB_AUTH=required`` (the shared ``service``
fixture runs with auth off).  It uses the run's PostgreSQL database but a Redis
database of its own, consumed by two workers started here, one per queue, as
the README's two-slot heavy deployment: ``-Q trajlab.heavy --concurrency=2``
and ``-Q trajlab.jobs --concurrency=1``.  Keys are made with the real CLI.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import uuid

import pytest
from fastapi.testclient import TestClient

from app.service import jobs
from app.service.broker import QUEUE_HEAVY, QUEUE_JOBS
from app.api.main import create_app
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings
from tests.integration.conftest import REDIS_URL, ROOT, claim_redis_db
from tests.integration.live import stop_group

pytestmark = pytest.mark.integration

QUICK = {"kind": "intercept", "preset": "long-range-intercept",
         "params": {"methods": ["impulsive"], "scan": {"step_s": 5.0}}}
# 1000 x 5000 NSGA-II, the largest allowed: cost 1,000,000 (heavy queue), most of a minute of work on any CPU
# (100 x 5000 took 4.6 s here: a quick job queued behind it could outlast it); cancelled at the end.
HEAVY = {"kind": "midcourse", "preset": "upper-stage-two-corrections",
         "params": {"population": 1000, "generations": 5000, "seed": 5}}


class Secure:
    def __init__(self, client: TestClient, env: dict, keys: dict[str, str]):
        self.client, self.env, self.keys = client, env, keys

    def h(self, who: str) -> dict:
        return {"Authorization": f"Bearer {self.keys[who]}"}

    def submit(self, who: str, body: dict):
        return self.client.post("/v1/jobs", json=body, headers=self.h(who))

    def wait(self, who: str, job_id: str, until: tuple[str, ...], timeout: float) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            job = self.client.get(f"/v1/jobs/{job_id}", headers=self.h(who)).json()
            if job["status"] in until:
                return job
            assert time.monotonic() < deadline, f"job {job_id} still {job['status']} after {timeout} s"
            time.sleep(0.2)


def _cli(env: dict, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "app.cli.commands", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=60)


def _worker(env: dict, log_dir, *, queue: str, concurrency: int) -> subprocess.Popen:
    name = f"sec-{queue.split('.')[-1]}-{uuid.uuid4().hex[:6]}@%h"
    log = open(log_dir / f"{name.split('@')[0]}.log", "wb")
    cmd = [sys.executable, "-m", "celery", "-A", "worker.celery_app:celery_app", "worker", "--loglevel=INFO",
           f"--concurrency={concurrency}", "-n", name, "-Q", queue]
    return subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


@pytest.fixture(scope="module")
def secure(pg_url, tmp_path_factory):
    upgrade(pg_url)
    r, broker_url = claim_redis_db(REDIS_URL)  # our own queues: no other test's worker takes our jobs
    log_dir = tmp_path_factory.mktemp("security")
    overrides = {"TRAJLAB_DATABASE_URL": pg_url, "TRAJLAB_BROKER_URL": broker_url, "TRAJLAB_AUTH": "required",
                 "TRAJLAB_HEARTBEAT_INTERVAL_S": "0.5", "TRAJLAB_MAX_ACTIVE_COST_PER_OWNER": "1500000"}
    env = {**os.environ, **overrides, "PYTHONPATH": str(ROOT)}
    suffix = uuid.uuid4().hex[:6]  # key names are unique per database; the database is shared by the run
    keys = {}
    for who, extra in (("alice", ()), ("bob", ()), ("ops", ("--admin",)), ("heavy1", ()), ("heavy2", ())):
        out = _cli(env, "keys", "create", "--name", f"{who}-{suffix}", *extra)
        assert out.returncode == 0, out.stderr
        keys[who] = out.stdout.strip()
    settings = Settings(**{k.removeprefix("TRAJLAB_").lower(): v for k, v in overrides.items()})
    workers = [_worker(env, log_dir, queue=QUEUE_HEAVY, concurrency=2),
               _worker(env, log_dir, queue=QUEUE_JOBS, concurrency=1)]
    client = TestClient(create_app(settings))
    try:
        yield Secure(client, env, keys | {"suffix": suffix})
    finally:
        for w in workers:
            stop_group(w)
        client.close()
        r.flushdb()  # also releases the run lock of this Redis database


def test_no_key_and_a_revoked_key_are_401(secure):
    r = secure.client.get("/v1/jobs")
    assert r.status_code == 401 and r.headers["WWW-Authenticate"] == "Bearer"
    created = _cli(secure.env, "keys", "create", "--name", f"temp-{secure.keys['suffix']}")
    key = created.stdout.strip()
    assert secure.client.get("/v1/jobs", headers={"Authorization": f"Bearer {key}"}).status_code == 200
    assert _cli(secure.env, "keys", "revoke", f"temp-{secure.keys['suffix']}").returncode == 0
    r = secure.client.get("/v1/jobs", headers={"Authorization": f"Bearer {key}"})
    assert r.status_code == 401
    listing = _cli(secure.env, "keys", "list").stdout
    assert f"temp-{secure.keys['suffix']}" in listing and key not in listing


def _job_routes(app) -> list[tuple[str, str]]:
    """Every documented route that addresses one job (get, result, cancel, events, and any added
    later, e.g. plots and reports), plus the console's per-job numbers."""
    found = [("GET", "/console/jobs/{job_id}/numbers"), ("GET", "/console/jobs/{job_id}/summary"),
             ("GET", "/console/jobs/{job_id}/last-iterate/{name}.png")]
    for path, ops in app.openapi()["paths"].items():
        if "{job_id}" in path:
            found += [(method.upper(), path) for method in ops if method in ("get", "post", "put", "delete")]
    return found


def test_owners_are_isolated_over_http(secure):
    job = secure.submit("alice", QUICK).json()
    done = secure.wait("alice", job["id"], ("succeeded", "failed"), timeout=120)
    assert done["status"] == "succeeded", done
    routes = _job_routes(secure.client.app)
    assert {("GET", "/v1/jobs/{job_id}"), ("GET", "/v1/jobs/{job_id}/result"),
            ("POST", "/v1/jobs/{job_id}/cancel"), ("GET", "/v1/jobs/{job_id}/events")} <= set(routes)
    for method, path in routes:
        url = path.replace("{job_id}", job["id"])
        url = url.replace("{", "").replace("}", "")  # any further path parameter: a placeholder
        # the owner's DELETE would end the walk: it is made last, below
        mine = secure.client.request(method, url, headers=secure.h("alice")) if method != "DELETE" else None
        theirs = secure.client.request(method, url, headers=secure.h("bob"))
        # a further path parameter may be refused (422) before the job is looked up: that discloses nothing
        refused = (404, 422) if path.count("{") > 1 else (404,)
        assert theirs.status_code in refused, (method, path, theirs.status_code)
        if mine is None:
            continue
        # the owner sees it, except a file this job does not have (an OEM needs a finite-thrust trajectory)
        assert mine.status_code != 404 or path.count("{") > 1 or path.endswith(".oem"), (method, path)
    # the job list's headline column names only the caller's jobs
    assert secure.client.get("/console/headlines", params={"ids": job["id"]}, headers=secure.h("bob")).json() == {}
    assert job["id"] in secure.client.get("/console/headlines", params={"ids": job["id"]},
                                          headers=secure.h("alice")).json()
    # Bob's cancel changed nothing; listings hold only the caller's jobs; the admin sees them all.
    assert secure.client.get(f"/v1/jobs/{job['id']}", headers=secure.h("alice")).json()["status"] == "succeeded"
    bob_job = secure.submit("bob", QUICK).json()
    alice_ids = {j["id"] for j in secure.client.get("/v1/jobs?limit=500", headers=secure.h("alice")).json()["items"]}
    bob_ids = {j["id"] for j in secure.client.get("/v1/jobs?limit=500", headers=secure.h("bob")).json()["items"]}
    all_ids = {j["id"] for j in secure.client.get("/v1/jobs?limit=500", headers=secure.h("ops")).json()["items"]}
    assert job["id"] in alice_ids and bob_job["id"] not in alice_ids
    assert bob_job["id"] in bob_ids and job["id"] not in bob_ids
    assert {job["id"], bob_job["id"]} <= all_ids
    assert secure.client.get(f"/v1/jobs/{job['id']}/result", headers=secure.h("ops")).status_code == 200
    secure.wait("bob", bob_job["id"], ("succeeded", "failed"), timeout=120)
    assert secure.client.delete(f"/v1/jobs/{job['id']}", headers=secure.h("alice")).status_code == 204


def test_inputs_that_were_500s_are_422_and_store_nothing(secure):
    before = secure.client.get("/v1/jobs", headers=secure.h("bob")).json()["total"]
    for label in ("a\u0000b", "\ud800"):
        body = json.dumps({"kind": "intercept", "label": label})  # ensure_ascii: sent as \u escapes
        r = secure.client.post("/v1/jobs", content=body,
                               headers={**secure.h("bob"), "Content-Type": "application/json"})
        assert r.status_code == 422, (label.encode("unicode_escape"), r.status_code, r.text[:200])
    r = secure.client.post("/v1/jobs", json={"kind": "intercept", "label": "z" * 500_000}, headers=secure.h("bob"))
    assert r.status_code == 422 and len(r.content) < 2000
    r = secure.client.post("/v1/jobs", json={"kind": "intercept", "label": "z" * 2_000_000}, headers=secure.h("bob"))
    assert r.status_code == 413
    assert secure.client.get("/v1/jobs", headers=secure.h("bob")).json()["total"] == before


def test_readyz_says_up_without_internals(secure):
    deadline = time.monotonic() + 90  # the workers' recovery candidates start with them (worker.recovery_duty)
    while (r := secure.client.get("/readyz")).status_code != 200 and time.monotonic() < deadline:
        time.sleep(0.5)
    body = r.json()  # every component up, the recovery heartbeat included (app.api.routes.health)
    assert r.status_code == 200 and body["status"] == "ready" and {"database", "broker", "recovery"} <= set(body)
    assert all(v == "up" for k, v in body.items() if k != "status"), body


def test_quick_job_finishes_while_two_heavy_jobs_hold_the_heavy_workers(secure):
    heavy = [secure.submit(who, HEAVY).json() for who in ("heavy1", "heavy2")]
    try:
        db = secure.client.app.state.db
        for who, job in zip(("heavy1", "heavy2"), heavy):
            assert job["status"] == "queued" and jobs.get_job(db, job["id"]).queue == QUEUE_HEAVY, job
            secure.wait(who, job["id"], ("running",), timeout=90)
        # The cost budget (1,500,000 here) refuses a second 1,000,000 job of the same owner.
        r = secure.submit("heavy1", HEAVY)
        assert r.status_code == 429 and int(r.headers["Retry-After"]) > 0 and "budget" in r.json()["detail"]
        t0 = time.monotonic()
        quick = secure.submit("alice", QUICK).json()
        assert jobs.get_job(db, quick["id"]).queue == QUEUE_JOBS
        done = secure.wait("alice", quick["id"], ("succeeded", "failed"), timeout=60)
        elapsed = time.monotonic() - t0
        assert done["status"] == "succeeded", done
        print(f"quick job behind two running heavy jobs: {elapsed:.1f} s")
        # the promise is a state, not a speed: the quick job ran while both heavy jobs held their slot
        for who, job in zip(("heavy1", "heavy2"), heavy):
            assert secure.client.get(f"/v1/jobs/{job['id']}", headers=secure.h(who)).json()["status"] == "running"
    finally:
        for who, job in zip(("heavy1", "heavy2"), heavy):
            secure.client.post(f"/v1/jobs/{job['id']}/cancel", headers=secure.h(who))
        for who, job in zip(("heavy1", "heavy2"), heavy):
            assert secure.wait(who, job["id"], ("cancelled", "failed", "succeeded"), timeout=90)["status"] == "cancelled"


def test_studies_are_isolated_between_owners(secure):
    body = {"kind": "intercept", "preset": "long-range-intercept", "mode": "independent",
            "params": {"methods": ["impulsive"], "scan": {"step_s": 5.0}},
            "sweeps": [{"path": "intercept_time_s", "values": [8080.5, 8500.0]}]}
    r = secure.client.post("/v1/studies", json=body, headers=secure.h("alice"))
    assert r.status_code == 202, r.text
    study_id = r.json()["id"]
    assert secure.client.post("/v1/studies", json=body).status_code == 401
    for method, path in (("GET", "/v1/studies/{id}"), ("GET", "/v1/studies/{id}/result"),
                         ("GET", "/v1/studies/{id}/plot.png"), ("POST", "/v1/studies/{id}/cancel")):
        r = secure.client.request(method, path.format(id=study_id), headers=secure.h("bob"))
        assert r.status_code == 404, (method, path, r.status_code)
    assert study_id not in [s["id"] for s in secure.client.get("/v1/studies", headers=secure.h("bob")).json()]
    assert study_id in [s["id"] for s in secure.client.get("/v1/studies", headers=secure.h("alice")).json()]
    assert study_id in [s["id"] for s in secure.client.get("/v1/studies", headers=secure.h("ops")).json()]
    rows = secure.client.get(f"/v1/studies/{study_id}/result", headers=secure.h("alice")).json()["rows"]
    for row in rows:  # the points are alice's jobs
        assert secure.client.get(f"/v1/jobs/{row['job_id']}", headers=secure.h("bob")).status_code == 404
        assert secure.client.get(f"/v1/jobs/{row['job_id']}", headers=secure.h("alice")).status_code == 200


def test_a_warm_start_never_reads_another_owners_result(secure):
    brach = {"kind": "ocp", "preset": "brachistochrone"}
    own = secure.submit("alice", brach).json()
    assert secure.wait("alice", own["id"], ("succeeded", "failed"), timeout=120)["status"] == "succeeded"
    # bob names alice's job: it reads as a job that does not exist (a 422 at the door, issue 28), and nothing
    # of alice's is used
    theirs = secure.submit("bob", {**brach, "params": {"initial_guess": {"from_job": own["id"]}}})
    assert theirs.status_code == 422, theirs.text
    assert theirs.json()["message"] == f"params.initial_guess.from_job: job {own['id']} does not exist"
    # alice's own warm start from it works
    mine = secure.submit("alice", {**brach, "params": {"initial_guess": {"from_job": own["id"]}}}).json()
    assert secure.wait("alice", mine["id"], ("succeeded", "failed"), timeout=120)["status"] == "succeeded"
