"""docs/architecture.md "How to add a kind", followed once: a throwaway kind declared in this module (a
KindSpec and nothing else: no edit of the registry, of the shared code or of the contracts), registered by
``TRAJLAB_EXTRA_KINDS`` (``app.kinds.register_kind``) in a real ``trajlab api`` and a real Celery worker on
real PostgreSQL and Redis, then submitted over HTTP: charged to its owner's quota, refused for memory past
``TRAJLAB_JOB_MEMORY_MB``, run, and its CSV served.

This module is imported by those two processes to register the kind, so its top level imports nothing
of the API (the submission schema is built from the registry once it is complete) and no test helper;
the fixtures import theirs.
"""
from __future__ import annotations

import math

import pytest
from pydantic import Field

from app.kinds.base import JobContext, KindSpec, MemoryModel, RunOutcome, StrictModel
from app.results.tables import columns_at
from tests.support import wait_serving

KIND = "throwaway"


class ThrowawayParams(StrictModel):
    """A made-up problem whose size drives its cost and memory."""

    size: int = Field(default=30, ge=2, le=1_000_000, description="Points of the trajectory", examples=[30])


def run(params: ThrowawayParams, ctx: JobContext) -> RunOutcome:
    t = [i / (params.size - 1) for i in range(params.size)]
    ctx.progress(0.5, f"{params.size} points")
    return RunOutcome("succeeded", result={"trajectory": {"t_s": t, "x_m": [math.sin(v) for v in t]},
                                           "notes": ["a throwaway kind"]})


SPEC = KindSpec(
    kind=KIND,
    params_model=ThrowawayParams,
    run=run,
    summary="A throwaway kind, declared in a test",
    cost=lambda p: float(p.get("size", 30)),                 # one work unit per point
    memory=MemoryModel(floor_mb=100.0, size=lambda p: float(p.get("size", 30)), floor_size=30.0,
                       per_unit_mb=1.0, grows_with="size"),  # 1 MB per point past 30
    tables={"trajectory": columns_at("trajectory")},
    time_limit_s=120.0,
)

BUDGET = 50          # TRAJLAB_MAX_ACTIVE_COST_PER_OWNER: one job of size 30 fits, two do not
MEMORY_CAP_MB = 1000  # TRAJLAB_JOB_MEMORY_MB: size 5000 needs 0.9 x (100 + 4970) MB


@pytest.fixture(scope="module")
def stack(tmp_path_factory):
    """``trajlab api`` (auth required) and, once a test starts it, a worker: both with TRAJLAB_EXTRA_KINDS."""
    import os
    import subprocess
    import sys
    import uuid

    import httpx
    import psycopg

    from app.api.auth import create_key
    from app.runtime.db import get_database
    from app.runtime.migrate import upgrade
    from app.service.broker import QUEUES
    from tests.integration.conftest import PG_ADMIN_URL, REDIS_URL, ROOT, claim_redis_db
    from tests.integration.live import free_port, stop_group

    logs = tmp_path_factory.mktemp("throwaway")
    name = f"trajlab_kind_{uuid.uuid4().hex[:10]}"
    with psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5) as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
    db_url = PG_ADMIN_URL.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1) + f"/{name}"
    upgrade(db_url)
    db = get_database(db_url)
    _, key = create_key(db, name="throwaway-user", owner="someone")
    db.dispose()
    redis, redis_url = claim_redis_db(REDIS_URL)
    port = free_port()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TRAJLAB_DATABASE_URL": db_url, "TRAJLAB_BROKER_URL": redis_url,
           "TRAJLAB_AUTH": "required", "TRAJLAB_API_WORKERS": "1", "TRAJLAB_EXTRA_KINDS": __name__,
           "TRAJLAB_MAX_ACTIVE_COST_PER_OWNER": str(BUDGET), "TRAJLAB_JOB_MEMORY_MB": str(MEMORY_CAP_MB),
           "TRAJLAB_HEARTBEAT_INTERVAL_S": "0.5"}
    env.pop("PROMETHEUS_MULTIPROC_DIR", None)  # `trajlab api` makes its own
    procs: list[subprocess.Popen] = []

    def spawn(what: str, cmd: list[str]) -> None:
        procs.append(subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=open(logs / f"{what}.log", "wb"),
                                      stderr=subprocess.STDOUT, start_new_session=True))

    def start_worker() -> None:
        spawn("worker", [sys.executable, "-m", "celery", "-A", "worker.celery_app:celery_app", "worker",
                         "--loglevel=INFO", "--concurrency=1", "-n", f"kind-{uuid.uuid4().hex[:6]}@%h",
                         "-Q", ",".join(QUEUES)])

    spawn("api", [sys.executable, "-m", "app.cli.commands", "api", "--host", "127.0.0.1", "--port", str(port)])
    client = httpx.Client(base_url=f"http://127.0.0.1:{port}", headers={"Authorization": f"Bearer {key}"},
                          timeout=30)
    wait_serving(f"http://127.0.0.1:{port}/healthz", proc=procs[-1], what="trajlab api",
                 log=logs / "api.log")
    try:
        yield client, start_worker, logs
    finally:
        client.close()
        for proc in procs:
            stop_group(proc)
        redis.flushdb()  # also releases the run lock
        with psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


def _wait(client, job_id: str, logs, timeout: float = 120.0) -> dict:
    import time

    deadline = time.monotonic() + timeout
    while True:
        job = client.get(f"/v1/jobs/{job_id}").json()
        if job["status"] in ("succeeded", "failed", "cancelled"):
            return job
        assert time.monotonic() < deadline, f"job {job_id} still {job['status']} (worker log {logs / 'worker.log'})"
        time.sleep(0.2)


@pytest.mark.integration
def test_a_kind_declared_in_a_test_is_charged_refused_for_memory_run_and_its_csv_served(stack):
    client, start_worker, logs = stack
    assert KIND in client.get("/openapi.json").json()["components"]["schemas"]["ThrowawaySubmission"][
        "properties"]["kind"]["const"]

    # charged: no worker yet, so the first job stays queued and holds its cost (30 of the budget of 50)
    first = client.post("/v1/jobs", json={"kind": KIND, "params": {"size": 30}})
    assert first.status_code == 202, first.text
    second = client.post("/v1/jobs", json={"kind": KIND, "params": {"size": 30}})
    assert second.status_code == 429, second.text
    message = second.json()["detail"]
    assert "estimated cost 30 on top of 30" in message and "TRAJLAB_MAX_ACTIVE_COST_PER_OWNER" in message, message

    # refused for memory, before the quota and before anything is stored
    big = client.post("/v1/jobs", json={"kind": KIND, "params": {"size": 5000}})
    assert big.status_code == 422, big.text
    assert "TRAJLAB_JOB_MEMORY_MB" in big.text and "grows with size" in big.text, big.text
    assert client.get("/v1/jobs", params={"kind": KIND}).json()["total"] == 1

    # run by a real worker that registered the kind from the same setting, and its CSV served
    start_worker()
    done = _wait(client, first.json()["id"], logs)
    assert done["status"] == "succeeded", done
    files = client.get(f"/v1/jobs/{done['id']}/plots").json()
    assert [t["name"] for t in files["tables"]] == ["trajectory"] and files["oem"] is None
    csv = client.get(f"/v1/jobs/{done['id']}/result.csv", params={"table": "trajectory"})
    assert csv.status_code == 200 and csv.headers["content-type"].startswith("text/csv")
    lines = csv.text.splitlines()
    assert lines[0] == "t_s,x_m" and len(lines) == 31
    assert float(lines[-1].split(",")[1]) == pytest.approx(math.sin(1.0), rel=1e-15)

    # its cost is released once it finished: the same job is admitted now
    again = client.post("/v1/jobs", json={"kind": KIND, "params": {"size": 30}})
    assert again.status_code == 202, again.text
    assert _wait(client, again.json()["id"], logs)["status"] == "succeeded"
