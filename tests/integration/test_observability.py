"""Issue 29: the metrics read by a real Prometheus, the request id from an API call to its worker's log lines,
and the dashboard's and alert rules' metrics present in a scrape (tests/integration/ops_stack.py)."""
from __future__ import annotations

import time
import uuid

import httpx
import pytest

from tests.integration.ops_stack import OpsStack, json_lines, wait_until
from tests.unit.test_ops_files import metric_names_in_ops_files

pytestmark = pytest.mark.integration
JOBS = 3
IMPULSIVE = {"methods": ["impulsive"]}


@pytest.fixture(scope="module")
def ops(tmp_path_factory, pg_url, redis_url):
    # pg_url/redis_url: the suite's reachability checks (a clear stop when PostgreSQL or Redis is down)
    stack = OpsStack(tmp_path_factory.mktemp("ops"))
    try:
        stack.start()
        stack.start_prometheus()
        yield stack
    finally:
        stack.stop()


def _submit(ops: OpsStack, request_id: str | None = None) -> httpx.Response:
    headers = {"Authorization": f"Bearer {ops.user_key}"}
    if request_id:
        headers["X-Request-ID"] = request_id
    return httpx.post(f"{ops.url}/v1/jobs", json={"kind": "intercept", "preset": "long-range-intercept",
                                                  "params": IMPULSIVE}, headers=headers, timeout=30)


def _wait(ops: OpsStack, job_id: str) -> dict:
    def done():
        job = httpx.get(f"{ops.url}/v1/jobs/{job_id}", headers={"Authorization": f"Bearer {ops.user_key}"},
                        timeout=10).json()
        return job if job["status"] in ("succeeded", "failed", "cancelled") else None
    return wait_until(done, timeout=180, what=f"job {job_id} finished", interval=0.5)


def _earlier_jobs(ops: OpsStack) -> int:
    """How many jobs the module's other tests left (they may run first: --random-order), once all are final:
    the counts below are read as that many plus this test's (every earlier one an intercept that succeeded)."""
    def settled():
        page = httpx.get(f"{ops.url}/v1/jobs", params={"limit": 200},
                         headers={"Authorization": f"Bearer {ops.admin_key}"}, timeout=10).json()
        assert all(job["status"] == "succeeded" for job in page["items"]), page["items"]
        return page if all(job["status"] in ("succeeded", "failed", "cancelled") for job in page["items"]) else None
    return wait_until(settled, timeout=180, what="the earlier jobs final", interval=0.5)["total"]


def test_metrics_through_prometheus(ops):
    started = time.time()
    before = _earlier_jobs(ops)
    ids = []
    for _ in range(JOBS):
        r = _submit(ops)
        assert r.status_code == 202, r.text
        assert r.headers["X-Request-ID"]  # made up when the caller sends none
        ids.append(r.json()["id"])
    for job_id in ids:
        assert _wait(ops, job_id)["status"] == "succeeded"

    def reads(expr: str, expected: float):
        return wait_until(lambda: ops.value(expr) == expected, timeout=30, what=f"{expr} == {expected}")

    reads("sum(trajlab_jobs_submitted_total)", before + JOBS)
    reads('trajlab_jobs_submitted_total{kind="intercept"}', before + JOBS)
    reads('trajlab_jobs_finished_total{kind="intercept",status="succeeded"}', before + JOBS)
    reads('sum(trajlab_jobs_finished_total{status!="succeeded"})', 0)
    reads('trajlab_job_duration_seconds_count{kind="intercept"}', before + JOBS)
    reads('trajlab_job_queue_wait_seconds_count{kind="intercept"}', before + JOBS)
    reads('trajlab_jobs_running{kind="intercept"}', 0)
    reads('sum(trajlab_queue_depth)', 0)
    # counted in both API processes' files and summed: every POST, whichever process took it
    reads('sum(trajlab_http_requests_total{method="POST",route="/v1/jobs",status="202"})', before + JOBS)
    wait_until(lambda: ops.value('sum(trajlab_http_request_duration_seconds_count{route="/v1/jobs/{job_id}"})'),
               timeout=30, what="the polls' latencies, by route template")
    assert ops.value("sum(trajlab_job_duration_seconds_sum)") > 0
    assert ops.value('up{job="trajlab"}') == 1
    assert ops.value("trajlab_worker_restarts_total") >= 1
    assert ops.value("trajlab_jobs_reaped_total") == 0
    assert ops.value("trajlab_jobs_republished_total") == 0
    # the broker's memory, read from Redis at scrape time (its maxmemory: 0 when it has none)
    assert ops.value("trajlab_broker_memory_used_bytes") > 0
    assert ops.value("trajlab_broker_maxmemory_bytes") >= 0
    beat = ops.value("trajlab_recovery_heartbeat_timestamp_seconds")
    assert beat is not None and beat >= started - 5
    info = ops.query("trajlab_build_info")
    assert len(info) == 1 and info[0]["metric"]["version"] == "0.1.0" and info[0]["metric"]["commit"]


def test_metrics_need_an_admin_key(ops):
    assert httpx.get(f"{ops.url}/metrics", timeout=10).status_code == 401
    user = httpx.get(f"{ops.url}/metrics", headers={"Authorization": f"Bearer {ops.user_key}"}, timeout=10)
    assert user.status_code == 403
    admin = httpx.get(f"{ops.url}/metrics", headers={"Authorization": f"Bearer {ops.admin_key}"}, timeout=10)
    assert admin.status_code == 200 and admin.headers["content-type"].startswith("text/plain")


def test_request_id_from_api_to_worker_log_lines(ops):
    request_id = f"it-{uuid.uuid4().hex}"
    r = _submit(ops, request_id)
    assert r.status_code == 202 and r.headers["X-Request-ID"] == request_id
    job_id = r.json()["id"]
    assert _wait(ops, job_id)["status"] == "succeeded"

    api = [line for line in json_lines(ops.dir / "api.log") if line.get("request_id") == request_id]
    assert any(job_id in line["message"] and line["logger"] == "trajlab.api" for line in api), api
    for line in api:
        assert set(line) >= {"time", "level", "logger", "message", "request_id", "job_id", "kind", "owner"}

    def worker_lines():
        lines = [line for line in json_lines(ops.dir / "worker.log") if line.get("request_id") == request_id]
        return lines if any(f"job {job_id} attempt 1 started" in line["message"] for line in lines) else None
    lines = wait_until(worker_lines, timeout=30, what="the worker's lines of the job")
    assert all(line["job_id"] == job_id and line["kind"] == "intercept" and line["owner"] == "someone"
               for line in lines), lines
    # a key never reaches a log line
    for name in ("api.log", "worker.log", "recover.log"):
        text = (ops.dir / name).read_text(errors="replace")
        assert ops.user_key not in text and ops.admin_key not in text


def test_every_metric_of_the_dashboard_and_rules_is_scraped(ops):
    scraped = {line.split("{", 1)[0].split(" ", 1)[0]
               for line in httpx.get(f"{ops.url}/metrics", headers={"Authorization": f"Bearer {ops.admin_key}"},
                                     timeout=10).text.splitlines() if line and not line.startswith("#")}
    names = metric_names_in_ops_files()
    assert names, "no metric found in deploy/"
    missing = sorted(name for name in names if name not in scraped)
    assert not missing, f"named in deploy/ but not in a scrape: {missing}"
