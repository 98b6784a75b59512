"""Issue 36 item 2: an API host and a worker host that silently lose Redis (packets dropped).

An API (``trajlab api``, one process) and a worker each on a host of their own (network namespaces,
tests/faults/hosts.py), each reaching this test's PostgreSQL and Redis over separate links; the Redis links
of both are cut (link down: packets go nowhere, no reset, no error) while a job runs on the worker, and the
API is driven through a bounded burst on every route a client uses (submit, read, list, cancel, a study
and its reads, /readyz, /metrics), after the same burst before the cut.  Then

* the API kept its latency: the burst's p99 during the cut is under the issue's 0.5 s plus the p99 of the
  same burst measured just before the cut (that margin is what a loaded 2-core machine adds to these very
  requests in this very run; idle, it is a few hundredths of a second; before the fix, every POST waited
  out the 5 s Redis timeout);
* ``/readyz`` says the broker is down during the cut, at once;
* the worker logged the loss within the health-check interval the README states (10 s);
* once the links are back, no accepted job is lost (each succeeded, or is cancelled because the burst
  cancelled it), every job and study point not cancelled has ``published_at`` set, and the metrics of the job that
  finished during the cut reached Redis: the duration histogram counts exactly the runs the worker stored.

The figures are printed (``pytest -s``).  Root only (``ip netns``).
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import threading
import time
from collections import defaultdict

import httpx
import psycopg
import pytest
import redis as redis_lib

from app.runtime.settings import Settings
from app.service.metrics import PREFIX
from tests.faults.conftest import FINAL, QUICK, ROOT, Stack, namespaced_stack, report
from tests.faults.hosts import Host
from tests.integration.live import free_port, stop_group
from tests.support import wait_serving

pytestmark = [pytest.mark.integration, pytest.mark.faults,
              pytest.mark.skipif(os.geteuid() != 0, reason="network namespaces need root (CI runs as root)")]

# one link (subnet 10.230.<n>.0/24) each; apart from tests/faults/test_worker_hosts.py's 1-4
API_DB, API_REDIS, API_CLIENTS, W_DB, W_REDIS = 11, 12, 13, 14, 15
ROUNDS = 15  # rounds of the burst, before and during the cut: 8 requests each, a study every 5th
P99_BOUND_S = 0.5  # the bound
HEALTH_CHECK_S = Settings().redis_health_check_interval_s  # the README's 10 s, the worker's default
SHORT = QUICK  # the cheapest real job
# running when the links die, for seconds at least: the finite-thrust solve (IPOPT on the LGL mesh); the
# impulsive scan alone once took seconds but takes 16 ms since it is compiled, and ended before the cut
RUNNING = {"kind": "intercept", "preset": "long-range-intercept",
           "params": {"methods": ["finite_thrust"], "scan": {"step_s": 2.0}}}
STUDY = {**SHORT, "mode": "independent", "sweeps": [{"path": "scan.step_s", "values": [20.0, 30.0]}]}


@pytest.fixture
def cut_hosts(tmp_path):
    with namespaced_stack(tmp_path, {"api": [API_DB, API_REDIS, API_CLIENTS], "w": [W_DB, W_REDIS]},
                          serve=(API_DB, API_REDIS, W_DB, W_REDIS)) as both:
        yield both


def _over(url: str, link: int) -> str:
    return url.replace("127.0.0.1", Host.server_address(link))


def _db(stack: Stack) -> psycopg.Connection:
    """The test's one connection to the stack's PostgreSQL (never cut), reused by every poll below (they ran
    every 0.1 s, two connections each); autocommit: each query sees the latest commits."""
    return psycopg.connect(stack.pg.url.replace("+psycopg", ""), connect_timeout=5, autocommit=True)


def _rows(db: psycopg.Connection, ids: list[str]) -> dict[str, tuple]:
    rows = db.execute("SELECT id, status, published_at FROM jobs WHERE id = ANY(%s)", (ids,)).fetchall()
    return {r[0]: (r[1], r[2]) for r in rows}


def _tails(*logs, lines: int = 30) -> str:
    return "\n".join(f"--- {log.name}:\n" + "\n".join(log.read_text(errors="replace").splitlines()[-lines:])
                     for log in logs if log.exists())


def _study_points(db: psycopg.Connection, study_ids: list[str]) -> list[str]:
    return [r[0] for r in db.execute("SELECT id FROM jobs WHERE study_id = ANY(%s)", (study_ids,)).fetchall()]


def _burst(client: httpx.Client, *, cancelled: list[str], accepted: list[str], studies: list[str],
           ready_codes: list[int]) -> dict[str, list[float]]:
    """``ROUNDS`` rounds over every route; each request's seconds, by route."""
    took: dict[str, list[float]] = defaultdict(list)

    def timed(route: str, method: str, url: str, expect: tuple[int, ...], **kw) -> httpx.Response:
        t0 = time.monotonic()
        r = client.request(method, url, **kw)
        took[route].append(time.monotonic() - t0)
        assert r.status_code in expect, (route, r.status_code, r.text[:300])
        return r

    for i in range(ROUNDS):
        job = timed("POST /v1/jobs", "POST", "/v1/jobs", (202,), json=SHORT).json()["id"]
        accepted.append(job)
        timed("GET /v1/jobs/{id}", "GET", f"/v1/jobs/{job}", (200,))
        timed("GET /v1/jobs", "GET", "/v1/jobs", (200,), params={"limit": 20})
        if i % 5 == 4:
            timed("POST /v1/jobs/{id}/cancel", "POST", f"/v1/jobs/{job}/cancel", (202,))
            cancelled.append(job)
        if i % 5 == 0:
            studies.append(timed("POST /v1/studies", "POST", "/v1/studies", (202,), json=STUDY).json()["id"])
        timed("GET /v1/studies/{id}", "GET", f"/v1/studies/{studies[-1]}", (200,))
        ready_codes.append(timed("GET /readyz", "GET", "/readyz", (200, 503)).status_code)
        timed("GET /metrics", "GET", "/metrics", (200,))
    return took


def _p(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def _first_line(path, text: str, after: int) -> bool:
    return path.exists() and text in path.read_text(errors="replace")[after:]


def test_an_api_and_a_worker_silently_cut_from_redis(cut_hosts):
    stack, hosts = cut_hosts
    api_log, worker_log = stack.tmp / "api.log", stack.tmp / "worker.log"
    stack.start_worker(concurrency=1, env={"TRAJLAB_DATABASE_URL": _over(stack.pg.url, W_DB),
                                           "TRAJLAB_BROKER_URL": _over(stack.redis.url, W_REDIS)},
                       prefix=hosts["w"].exec_prefix())
    port = free_port()
    env = {**stack.env, "TRAJLAB_DATABASE_URL": _over(stack.pg.url, API_DB),
           "TRAJLAB_BROKER_URL": _over(stack.redis.url, API_REDIS), "TRAJLAB_API_WORKERS": "1"}
    api = subprocess.Popen([*hosts["api"].exec_prefix(), sys.executable, "-m", "app.cli.commands", "api", "--host",
                            Host.address(API_CLIENTS), "--port", str(port)], cwd=ROOT, env=env,
                           stdout=open(api_log, "ab"), stderr=subprocess.STDOUT, start_new_session=True)
    base = f"http://{Host.address(API_CLIENTS)}:{port}"
    accepted: list[str] = []
    cancelled: list[str] = []
    studies: list[str] = []
    db = _db(stack)
    try:
        stack.wait_ready()
        # ready: the database, the broker and the worker's recovery heartbeat (its start is no part of this)
        wait_serving(f"{base}/readyz", proc=api, what="trajlab api", log=api_log, status=200)
        # a client (its kept-alive connection) per phase: uvicorn closes a connection idle for 5 s, and a request
        # sent on it as it closes is reset, which no fix of ours is about
        ready_before: list[int] = []
        with httpx.Client(base_url=base, timeout=120) as client:
            before = _burst(client, cancelled=cancelled, accepted=accepted, studies=studies,
                            ready_codes=ready_before)
        deadline = time.monotonic() + 300  # the worker takes the next job at once: nothing queued before it
        while any(status not in FINAL for status, _ in _rows(db, accepted + _study_points(db, studies)).values()):
            assert time.monotonic() < deadline, "the jobs of the burst before the cut did not end"
            time.sleep(0.1)
        running = httpx.post(f"{base}/v1/jobs", json=RUNNING, timeout=120).json()["id"]
        accepted.append(running)
        deadline = time.monotonic() + 300
        while (row := _rows(db, [running])[running])[0] != "running":
            # a job that ended before we saw it running, or one never published, is a different failure: say which
            assert row[0] not in FINAL, f"the job meant to run through the cut ended {row[0]} before the cut; " \
                                        f"logs: {_tails(api_log, worker_log)}"
            assert time.monotonic() < deadline, f"the job meant to run through the cut never started " \
                                                f"(status {row[0]}, published_at {row[1]}); " \
                                                f"logs: {_tails(api_log, worker_log)}"
            time.sleep(0.05)
        worker_log_at = len(worker_log.read_text(errors="replace"))
        cut_at = hosts["api"].cut(API_REDIS)
        hosts["w"].cut(W_REDIS)
        noticed: list[float] = []

        def watch_worker_log() -> None:
            while time.monotonic() - cut_at < 120 and not noticed:
                if _first_line(worker_log, "broker unreachable", worker_log_at):
                    noticed.append(time.monotonic() - cut_at)
                time.sleep(0.1)
        watcher = threading.Thread(target=watch_worker_log)
        watcher.start()
        ready_during: list[int] = []
        with httpx.Client(base_url=base, timeout=120) as client:
            during = _burst(client, cancelled=cancelled, accepted=accepted, studies=studies,
                            ready_codes=ready_during)
        watcher.join()
        # the run through the cut ends (its result goes to PostgreSQL, reachable) and its metrics wait
        deadline = time.monotonic() + 300
        while _rows(db, [running])[running][0] not in FINAL:
            assert time.monotonic() < deadline, "the job running through the cut did not end"
            time.sleep(0.1)
        readyz_cut = httpx.get(f"{base}/readyz", timeout=120).json()
        cut_s = time.monotonic() - cut_at
        restored_at = hosts["api"].restore(API_REDIS)
        hosts["w"].restore(W_REDIS)
        ids = accepted + _study_points(db, studies)
        deadline = time.monotonic() + 300
        while True:  # every job final and every one published (asserted below, after the report)
            rows = _rows(db, ids)
            if all(status in FINAL and (published is not None or status == "cancelled")
                   for status, published in rows.values()):
                break
            if time.monotonic() > deadline:
                break
            time.sleep(0.25)
        settled_s = time.monotonic() - restored_at
    finally:
        stop_group(api)
        db.close()
    stored_runs = worker_log.read_text(errors="replace").count(" stored: ")
    r = redis_lib.Redis.from_url(stack.redis.url)
    deadline = time.monotonic() + 60  # the worker's buffer retries every 2 s (asserted below, after the report)
    while int(r.hget(PREFIX + "job_duration_seconds", "intercept|count") or 0) < stored_runs:
        if time.monotonic() > deadline:
            break
        time.sleep(0.25)
    recorded = int(r.hget(PREFIX + "job_duration_seconds", "intercept|count") or 0)
    # a cancelled job had maybe finished already (the worker is quick before the cut)
    lost = [j for j, (status, _) in rows.items()
            if not (status == "succeeded" or (status == "cancelled" and j in cancelled))]
    all_before = [t for ts in before.values() for t in ts]
    all_during = [t for ts in during.values() for t in ts]
    # a job cancelled while it waited for the broker is never sent: its published_at stays empty, truly
    unpublished = [j for j, (status, published) in rows.items() if published is None and status != "cancelled"]
    ms = lambda seconds: f"{seconds * 1000:.0f}ms"  # noqa: E731
    report("silent-redis-cut-api-and-worker", requests=len(all_during), median_before=ms(statistics.median(all_before)),
           p99_before=ms(_p(all_before, 0.99)), median_cut=ms(statistics.median(all_during)),
           p99_cut=ms(_p(all_during, 0.99)), max_cut=ms(max(all_during)),
           slowest_route=max(during, key=lambda k: max(during[k])), worker_noticed_s=noticed[0] if noticed else -1.0,
           jobs=len(ids), lost=len(lost), unpublished=len(unpublished), metrics_recorded=recorded, runs_stored=stored_runs, cut_s=cut_s,
           settled_after_restore_s=settled_s)
    assert not lost, [rows[j] for j in lost[:3]]
    assert not unpublished, [rows[j] for j in unpublished[:3]]
    # the API: no route waits on the lost broker (the margin: the module docstring)
    assert _p(all_during, 0.99) < P99_BOUND_S + _p(all_before, 0.99), {k: max(v) for k, v in during.items()}
    assert set(ready_before) == {200} and readyz_cut["broker"] == "down", readyz_cut
    assert ready_during.count(503) >= ROUNDS - 1  # at once: at most the first one found the broker up
    # the worker: within the health-check interval, measured from the cut by this test's 0.1 s polling
    assert noticed and noticed[0] < HEALTH_CHECK_S, noticed
    # the return is logged within a third of the health-check interval of the link coming back, which may be
    # after the API's probe saw it: wait for the state (bounded), never read the log once
    deadline = time.monotonic() + 60
    while not (_first_line(api_log, "broker reachable again", 0) and _first_line(worker_log, "broker reachable again", 0)):
        assert time.monotonic() < deadline, "the API and the worker log the broker's return"
        time.sleep(0.1)
    # the run that ended during the cut is counted, and nothing twice
    assert recorded == stored_runs, (recorded, stored_runs)
