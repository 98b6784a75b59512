"""Issue 30: workers on other hosts, and links that go dead.

Two worker hosts in network namespaces of their own (tests/faults/hosts.py), each reaching this
test's PostgreSQL and Redis over a veth pair only; the API and the recovery loop stay here.  Host a is
cut off (link down) for longer than the stale limit in the middle of a burst, then restored: no job
is lost, none is stored twice, its jobs are re-queued within the stated time and finished by host b, and
its slot is free again within the store-retry bound (``stale_after_s`` plus one bounded database call).  Then an API
on a third host whose database link is cut answers 503 with ``Retry-After`` at once, never a hung
request.  A study's points spread over both hosts, each stored once.  The figures are printed
(``pytest -s``).  Root only (``ip netns``).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time
from collections import Counter

import httpx
import psycopg
import pytest

from tests.faults.conftest import ROOT, Stack, namespaced_stack, report
from tests.faults.hosts import Host
from tests.integration.live import free_port, stop_group

pytestmark = [pytest.mark.integration, pytest.mark.faults,
              pytest.mark.skipif(os.geteuid() != 0, reason="network namespaces need root (CI runs as root)")]

A, B, API_DB, API_CLIENTS = 1, 2, 3, 4  # one link (subnet 10.230.<n>.0/24) each
# Tight network timeouts for the hosts, so the bounds fit in a short test (defaults: app.runtime.settings).
TIMEOUTS = {"TRAJLAB_DB_CONNECT_TIMEOUT_S": "3", "TRAJLAB_DB_TCP_USER_TIMEOUT_S": "5",
            "TRAJLAB_DB_KEEPALIVES_IDLE_S": "2", "TRAJLAB_DB_KEEPALIVES_INTERVAL_S": "1",
            "TRAJLAB_DB_KEEPALIVES_COUNT": "2", "TRAJLAB_DB_POOL_TIMEOUT_S": "5",
            "TRAJLAB_REDIS_SOCKET_TIMEOUT_S": "3", "TRAJLAB_REDIS_CONNECT_TIMEOUT_S": "2",
            "TRAJLAB_REDIS_HEALTH_CHECK_INTERVAL_S": "2"}
CALL_BOUND_S = 3 + 5 + 5  # connect + unacknowledged data + pool wait: the longest one database call may block
HEARTBEAT_JOIN_S = 10  # worker.context: a job's end waits this long at most for its heartbeat thread
LOAD_MARGIN_S = 10  # what a loaded machine (load average 6, a busy loop per core) adds to a bound
SHORT = {"kind": "intercept", "preset": "long-range-intercept",  # about a tenth of a second
         "params": {"methods": ["impulsive"], "scan": {"step_s": 2.0}}}
# Running when the link dies: the robust shuttle entry takes seconds warm (6.3 s here, load 2; the heavy pool
# of each host runs one). The fine impulsive scan once used here takes 0.17 s warm: a host's first one lasted
# only through its start-up, and one that ended before the cut would have voided the scenario.
LONG = {"kind": "robust_reentry", "preset": "robust-max-crossrange", "params": {"monte_carlo": {"samples": 2000}}}
LONG_JOBS = 4  # two per host: one running in each heavy pool at the cut, one queued behind it
# a study's points: a second or less each (the fine impulsive scan), so four are queued at once
SCAN = {"kind": "intercept", "preset": "long-range-intercept", "params": {"methods": ["impulsive"], "scan": {"step_s": 0.05}}}


@pytest.fixture
def hosts_stack(tmp_path):
    with namespaced_stack(tmp_path, {"a": [A], "b": [B], "api": [API_DB, API_CLIENTS]}) as both:
        yield both


def _urls(stack: Stack, link: int) -> dict:
    addr = Host.server_address(link)
    return {"TRAJLAB_DATABASE_URL": stack.pg.url.replace("127.0.0.1", addr),
            "TRAJLAB_BROKER_URL": stack.redis.url.replace("127.0.0.1", addr)}


def _workers_of(stack: Stack, job_ids: list[str]) -> dict[str, tuple[str, str | None, int]]:
    with psycopg.connect(stack.pg.url.replace("+psycopg", ""), connect_timeout=5) as conn:
        rows = conn.execute("SELECT id, status, worker, attempts FROM jobs WHERE id = ANY(%s)", (job_ids,)).fetchall()
    return {r[0]: (r[1], r[2], r[3]) for r in rows}


def _log_lines(stack: Stack, pattern: str) -> list[re.Match]:
    found = []
    for log in stack.tmp.glob("worker*.log"):
        found += list(re.finditer(pattern, log.read_text(errors="replace")))
    return found


def _slot_given_up(stack: Stack, job_ids: list[str]) -> bool:
    """Host a's worker logged the end of every one of these jobs' first attempt: refused or not stored."""
    return all(_log_lines(stack, rf"job {j} attempt 1(?: refused|: result not stored)") for j in job_ids)


def _longest_first_run_s(stack: Stack, job_ids: list[str]) -> float:
    """The longest run (claim to stored) among these jobs' first attempts that were stored."""
    with psycopg.connect(stack.pg.url.replace("+psycopg", ""), connect_timeout=5) as conn:
        runs = conn.execute("SELECT extract(epoch FROM finished_at - started_at) FROM jobs WHERE id = ANY(%s) "
                            "AND attempts = 1 AND status = 'succeeded'", (job_ids,)).fetchall()
    assert runs, "no long job ran to its end on its first attempt"
    return max(float(r[0]) for r in runs)


def test_a_worker_host_cut_off_longer_than_the_stale_limit_during_a_burst(hosts_stack):
    stack, hosts = hosts_stack
    stale_s = stack.settings.stale_after_s
    stack.start_worker(concurrency=1, name="worker-a", env={**_urls(stack, A), **TIMEOUTS},
                       prefix=hosts["a"].exec_prefix())
    stack.start_worker(concurrency=1, name="worker-b", env={**_urls(stack, B), **TIMEOUTS},
                       prefix=hosts["b"].exec_prefix())
    stack.start_recovery()
    accepted, codes = [], []
    # long jobs first: each host has a slot running one when the link dies
    accepted += [stack.submit(LONG).json()["id"] for _ in range(LONG_JOBS)]
    deadline = time.monotonic() + 180  # the workers' start: a minute with a busy loop per core (load average 15)
    while True:
        on_a = [j for j, (status, worker, _) in _workers_of(stack, accepted).items()
                if status == "running" and worker and "fault1@" in worker]
        if on_a:
            break
        assert time.monotonic() < deadline, "no long job ever ran on host a"
        time.sleep(0.2)
    stop = threading.Event()

    def burst():
        while not stop.is_set():
            r = stack.submit(SHORT)
            codes.append(r.status_code)
            if r.status_code == 202:
                accepted.append(r.json()["id"])
            time.sleep(0.2)

    thread = threading.Thread(target=burst)
    thread.start()
    on_a = [j for j, (status, worker, _) in _workers_of(stack, accepted).items()
            if status == "running" and worker and "fault1@" in worker] or on_a  # both of its pools, if both run one
    cut_at = hosts["a"].cut(A)
    # The cut lasts until the reaper has re-queued host a's jobs (past the stale limit, so the cut is longer
    # than it) and host a has given their slot up, or until a deadline far past both bounds below.
    requeued_s = slot_free_s = None
    while time.monotonic() - cut_at < stale_s + CALL_BOUND_S + 120:
        now = time.monotonic() - cut_at
        if requeued_s is None and all(s[2] > 1 for s in _workers_of(stack, on_a).values()):
            requeued_s = now
        if slot_free_s is None and _slot_given_up(stack, on_a):
            slot_free_s = now
        if requeued_s is not None and slot_free_s is not None:
            break
        time.sleep(0.25)
    restored_at = hosts["a"].restore(A)
    time.sleep(3.0)
    stop.set()
    thread.join()
    # Host b takes the re-queued jobs when one of its slots is free and they reach the head of the queue,
    # behind the burst's backlog: a time that grows with the machine's load, so the test waits for it.
    jobs, lost, _ = stack.outcome(accepted, timeout=300)
    if slot_free_s is None and _slot_given_up(stack, on_a):
        slot_free_s = time.monotonic() - cut_at  # freed only after the link came back (an upper bound)
    stored = Counter(m.group(1) for m in _log_lines(stack, r"job ([0-9a-f]{32}) attempt \d+ stored: "))
    twice = [j for j in accepted if stored[j] > 1]
    ran_on = {host: len(re.findall(r"attempt \d+ started", (stack.tmp / f"worker-{host}.log").read_text(errors="replace")))
              for host in ("a", "b")}
    taken_over = _workers_of(stack, on_a)
    long_s = _longest_first_run_s(stack, accepted[:LONG_JOBS])
    report("worker-host-cut", accepted=len(accepted), answered=len(codes), lost=len(lost), stored_twice=len(twice),
           started_on_a=ran_on["a"], started_on_b=ran_on["b"], cut_s=restored_at - cut_at, taken_over=len(on_a),
           requeued_s=requeued_s or -1.0, slot_free_s=slot_free_s or -1.0, long_job_s=long_s, stale_after_s=stale_s)
    assert ran_on["a"] > 0 and ran_on["b"] > 0  # jobs ran on both hosts
    assert set(codes) == {202}, Counter(codes)  # the API never noticed: host a was cut, not the API
    assert not lost, [jobs.get(j) for j in lost[:3]]
    assert not twice and all(stored[j] == 1 for j in accepted)
    # host a's jobs were re-queued and finished on their second attempt, by whichever heavy slot was free first:
    # host b's, or host a's own once its link was back (host b's slot may still hold its own long job)
    assert all(status == "succeeded" and attempts == 2 for status, _, attempts in taken_over.values()), taken_over
    # The reaper re-queues once the heartbeat is stale_after_s old; its pass runs every reaper_interval_s; if
    # host a held the recovery lease, another candidate takes the lease over within 4/3 of its length.  The
    # margin is what a loaded machine (load average 6) adds to a recovery pass and to this test's polling.
    settings = stack.settings
    requeue_bound_s = max(stale_s, 4 / 3 * settings.recovery_lease_s) + settings.reaper_interval_s + LOAD_MARGIN_S
    assert requeued_s is not None and requeued_s < requeue_bound_s, (requeued_s, requeue_bound_s)
    # The cut host gave its slot up: the long job's remaining seconds (at most one long job's run, measured on
    # this machine in this run), the heartbeat thread's join (it may sit in a call over the dead link), then
    # stale_after_s of store retries, each call bounded (CALL_BOUND_S).
    slot_bound_s = long_s + HEARTBEAT_JOIN_S + stale_s + CALL_BOUND_S + LOAD_MARGIN_S
    assert slot_free_s is not None and slot_free_s < slot_bound_s, (slot_free_s, slot_bound_s)
    # a job host a took as the link died (claimed after the look above, or its claim's commit in flight when the
    # link went) is host a's too: the reaper re-runs it once (a loaded run: two short jobs claimed at the cut)
    took_a = set(re.findall(r"job ([0-9a-f]{32})", (stack.tmp / "worker-a.log").read_text(errors="replace")))
    assert all(jobs[j]["attempts"] == 1 for j in accepted if j not in on_a and j not in took_a)
    assert all(jobs[j]["attempts"] <= 2 for j in accepted if j in took_a)


def test_the_api_cut_from_its_database_answers_503_with_retry_after(hosts_stack):
    stack, hosts = hosts_stack
    api = hosts["api"]
    port = free_port()
    env = {**stack.env, **TIMEOUTS, "TRAJLAB_DATABASE_URL": stack.pg.url.replace("127.0.0.1", Host.server_address(API_DB)),
           "TRAJLAB_BROKER_URL": stack.redis.url.replace("127.0.0.1", Host.server_address(API_CLIENTS)),
           "TRAJLAB_API_WORKERS": "1"}
    proc = subprocess.Popen([*api.exec_prefix(), sys.executable, "-m", "app.cli.commands", "api", "--host",
                             Host.address(API_CLIENTS), "--port", str(port)], cwd=ROOT, env=env,
                            stdout=open(stack.tmp / "api.log", "ab"), stderr=subprocess.STDOUT, start_new_session=True)
    base = f"http://{Host.address(API_CLIENTS)}:{port}"
    try:
        with httpx.Client(base_url=base, timeout=60) as client:
            # its start is no part of the scenario: waited for as long as a loaded machine needs (it took 60 s
            # with a busy loop per core and load average 15), as long as the process lives
            deadline = time.monotonic() + 240
            while True:
                try:
                    if client.get("/v1/jobs").status_code == 200:
                        break
                except httpx.TransportError:
                    pass
                assert proc.poll() is None and time.monotonic() < deadline, (stack.tmp / "api.log").read_text()[-2000:]
                time.sleep(0.3)
            assert client.post("/v1/jobs", json=SHORT).status_code == 202
            api.cut(API_DB)
            answers = []
            for i in range(8):
                t0 = time.monotonic()
                r = client.post("/v1/jobs", json=SHORT) if i % 2 else client.get("/v1/jobs")
                answers.append((r.status_code, r.headers.get("Retry-After"), time.monotonic() - t0))
            restored_at = api.restore(API_DB)
            deadline = time.monotonic() + 30
            while client.get("/v1/jobs").status_code != 200:
                assert time.monotonic() < deadline, "the API did not come back after the link"
                time.sleep(0.5)
            back_s = time.monotonic() - restored_at
    finally:
        stop_group(proc)
    slowest = max(a[2] for a in answers)
    report("api-cut-from-database", requests=len(answers), http_503=sum(a[0] == 503 for a in answers),
           slowest_answer_s=slowest, back_after_restore_s=back_s)
    assert all(code == 503 and retry_after for code, retry_after, _ in answers), answers
    assert slowest < CALL_BOUND_S + LOAD_MARGIN_S, answers  # bounded by the timeouts, not hung


def test_a_study_runs_across_two_worker_hosts(hosts_stack):
    """A study's points are ordinary jobs: with four points queued at once and two single-slot
    pools on each host (prefetch 1), both hosts take points; every point is stored once."""
    stack, hosts = hosts_stack
    for name, link in (("a", A), ("b", B)):
        stack.start_worker(concurrency=1, name=f"worker-{name}", env={**_urls(stack, link), **TIMEOUTS},
                           prefix=hosts[name].exec_prefix())
    stack.start_recovery()
    body = {**SCAN, "mode": "independent", "label": "across hosts",
            "sweeps": [{"path": "scan.step_s", "values": [0.05, 0.06, 0.07, 0.08]}]}
    r = stack.client.post("/v1/studies", json=body)
    assert r.status_code == 202, r.text
    study_id = r.json()["id"]
    deadline = time.monotonic() + 360  # two long points per host: 45 s each with a busy loop per core
    while (study := stack.client.get(f"/v1/studies/{study_id}").json())["status"] == "running":
        assert time.monotonic() < deadline, study
        time.sleep(0.5)
    rows = stack.client.get(f"/v1/studies/{study_id}/result").json()["rows"]
    ids = [row["job_id"] for row in rows]
    stored = Counter(m.group(1) for m in _log_lines(stack, r"job ([0-9a-f]{32}) attempt \d+ stored: "))
    hosts_of = {j: ("a" if "fault1@" in w else "b") for j, (_, w, _) in _workers_of(stack, ids).items()}
    report("study-across-hosts", points=len(rows), on_a=sum(h == "a" for h in hosts_of.values()),
           on_b=sum(h == "b" for h in hosts_of.values()))
    assert study["status"] == "finished" and [row["status"] for row in rows] == ["succeeded"] * 4, rows
    assert all(stored[j] == 1 for j in ids), stored
    assert set(hosts_of.values()) == {"a", "b"}, hosts_of
