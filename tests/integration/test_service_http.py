"""The job path end to end: HTTP -> PostgreSQL -> Redis -> a real Celery worker -> PostgreSQL -> HTTP."""
from __future__ import annotations

import os
import subprocess
import sys
import time
import uuid

import pytest

from app.runtime.migrate import check
from tests.support import wait_serving

pytestmark = pytest.mark.integration

IMPULSIVE = {"methods": ["impulsive"]}
# A midcourse NSGA-II run long enough to be caught running (progress per generation).
LONG = {"mode": "optimize", "corrections": 2, "population": 100, "generations": 2500, "seed": 7}


def _wait_running(service, job_id, timeout=60):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = service.client.get(f"/v1/jobs/{job_id}").json()
        if job["status"] == "running" and job["progress"] > 0:
            return job
        assert job["status"] in ("queued", "running"), job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} never started running")


def test_alembic_head_matches_models_on_postgres(service, pg_url):
    check(pg_url)  # raises if autogenerate would emit anything


def test_submit_runs_and_stores_the_number(service):
    r = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE, label="it-basic")
    assert r.status_code == 202, r.text
    job = r.json()
    assert r.headers["Location"] == f"/v1/jobs/{job['id']}"
    assert job["status"] == "queued" and job["params"]["methods"] == ["impulsive"]
    assert service.client.get(f"/v1/jobs/{job['id']}/result").status_code in (409, 200)
    done = service.wait(job["id"], timeout=120)
    assert done["status"] == "succeeded", done
    assert done["progress"] == 1.0 and done["started_at"] and done["finished_at"]
    best = service.result(job["id"])["impulsive"]["best"]
    assert best["delta_v_mps"] == pytest.approx(2302.48, abs=0.01)
    listed = service.client.get("/v1/jobs", params={"kind": "intercept", "status": "succeeded", "limit": 500}).json()
    assert job["id"] in [j["id"] for j in listed["items"]] and listed["total"] >= 1


def test_404_409_and_422(service):
    assert service.client.get("/v1/jobs/doesnotexist").status_code == 404
    assert service.client.get("/v1/jobs/doesnotexist/result").status_code == 404
    assert service.client.post("/v1/jobs/doesnotexist/cancel").status_code == 404
    before = service.client.get("/v1/jobs").json()["total"]
    bad = [
        ({"kind": "intercept", "params": {"interceptor": {"mass_kg": -5}}}, "mass_kg"),
        ({"kind": "intercept", "params": {"unknown_field": 1}}, "unknown_field"),
        ({"kind": "nope"}, "kind"),
        ({"kind": "intercept", "preset": "betts-max-crossrange"}, "preset"),
    ]
    for body, field in bad:
        r = service.client.post("/v1/jobs", json=body)
        assert r.status_code == 422, (body, r.text)
        assert field in r.text
    r = service.client.post("/v1/jobs", content=b'{"kind": "intercept", "params": {"g0_mps2": NaN}}',
                            headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert service.client.get("/v1/jobs", params={"limit": 501}).status_code == 422
    assert service.client.get("/v1/jobs").json()["total"] == before  # nothing stored


def test_idempotent_resubmission(service):
    key = {"Idempotency-Key": f"it-{uuid.uuid4().hex}"}
    a = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE, headers=key)
    b = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE, headers=key)
    assert a.status_code == b.status_code == 202
    assert a.json()["id"] == b.json()["id"]
    c = service.submit("intercept", preset="long-range-intercept", params={"methods": ["impulsive"], "g0_mps2": 9.8},
                       headers=key)
    assert c.status_code == 422 and "Idempotency-Key" in c.text
    service.wait(a.json()["id"])


def test_cancel_queued_job_never_starts(service):
    service.stop_worker()
    try:
        job = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE).json()
        r = service.client.post(f"/v1/jobs/{job['id']}/cancel")
        assert r.status_code == 202 and r.json()["status"] == "cancelled"
    finally:
        service.start_worker()
    probe = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE).json()
    service.wait(probe["id"])  # the worker has drained the queue past the cancelled job
    again = service.client.get(f"/v1/jobs/{job['id']}").json()
    assert again["status"] == "cancelled" and again["started_at"] is None
    assert again["error"]["code"] == "cancelled"


def test_cancel_running_job_keeps_partial_front(service):
    job = service.submit("midcourse", preset="upper-stage-two-corrections", params=LONG).json()
    _wait_running(service, job["id"])
    assert service.client.post(f"/v1/jobs/{job['id']}/cancel").status_code == 202
    done = service.wait(job["id"], timeout=60)
    assert done["status"] == "cancelled", done
    body = service.client.get(f"/v1/jobs/{job['id']}/result")
    assert body.status_code == 409
    partial = body.json()["partial_result"]
    assert partial is not None and len(partial["pareto_front"]) > 0
    assert partial["generations"] < LONG["generations"]


def test_worker_killed_mid_job_is_requeued_by_reaper(service):
    # LONG runs for seconds on any CPU: the kill lands at the observed running state, not by timing
    job = service.submit("midcourse", preset="upper-stage-two-corrections", params=LONG).json()
    _wait_running(service, job["id"])
    service.kill_worker()  # SIGKILL to the whole process group: no warm shutdown, no ack
    stuck = service.client.get(f"/v1/jobs/{job['id']}").json()
    assert stuck["status"] == "running" and stuck["attempts"] == 1
    service.start_worker()
    done = service.wait(job["id"], timeout=180)
    assert done["status"] == "succeeded", done
    assert done["attempts"] == 2
    assert len(service.result(job["id"])["pareto_front"]) > 0


def test_production_process_commands(service, pg_url, redis_url):
    """The commands docker-compose runs (migrate, api) work outside Docker against the real services."""
    env = {**service.env}
    subprocess.run([sys.executable, "-m", "app.cli.commands", "migrate"], env=env, check=True, timeout=120)
    port = 18000 + os.getpid() % 1000
    api = subprocess.Popen([sys.executable, "-m", "app.cli.commands", "api", "--host", "127.0.0.1", "--port", str(port)],
                           env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        import httpx

        r = wait_serving(f"http://127.0.0.1:{port}/readyz", proc=api, what="trajlab api")
        body = r.json()  # every component up, the recovery heartbeat included (app.api.routes.health)
        assert r.status_code == 200 and body["status"] == "ready" and {"database", "broker", "recovery"} <= set(body)
        assert all(v == "up" for k, v in body.items() if k != "status"), body
        assert httpx.get(f"http://127.0.0.1:{port}/docs", timeout=5).status_code == 200
    finally:
        api.terminate()
        api.wait(timeout=30)


def test_a_duplicate_message_of_a_running_job_is_dropped(service):
    from app.service.broker import publish_job

    job = service.submit("midcourse", preset="upper-stage-two-corrections",
                         params=LONG).json()
    running = _wait_running(service, job["id"])
    # the same delivery message again (what a re-publish or a broker redelivery would send)
    app = service.client.app
    publish_job(app.state.celery, service.settings, job_id=job["id"], attempt=running["attempts"],
                kind="midcourse")
    done = service.wait(job["id"], timeout=180)
    assert done["status"] == "succeeded" and done["attempts"] == 1  # never taken over by its duplicate
    logs = "".join(p.read_text(errors="replace") for p in service.log_dir.glob("worker-*.log"))
    assert logs.count(f"job {job['id']} attempt 1 started") == 1
    assert f"delivery of job {job['id']} attempt 1 dropped" in logs
