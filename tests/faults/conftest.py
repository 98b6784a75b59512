"""A whole trajlab stack on servers of its own, for fault tests: the API (TestClient), real worker and
recovery processes, a Redis and a PostgreSQL that the tests stop, kill and restart."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.api.main import create_app
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings
from tests.faults.hosts import Host
from tests.faults.servers import PostgresServer, RedisServer
from tests.integration.live import stop_group

ROOT = Path(__file__).resolve().parents[2]
# The cheapest real job: the impulsive interception scan on a coarse grid (a few tens of ms).
QUICK = {"kind": "intercept", "preset": "long-range-intercept",
         "params": {"methods": ["impulsive"], "scan": {"step_s": 20.0}}}
FINAL = ("succeeded", "failed", "cancelled")


class Stack:
    def __init__(self, pg: PostgresServer, redis: RedisServer, tmp: Path, overrides: dict | None = None):
        self.pg, self.redis, self.tmp = pg, redis, tmp
        overrides = {"TRAJLAB_DATABASE_URL": pg.url, "TRAJLAB_BROKER_URL": redis.url, "TRAJLAB_AUTH": "off",
                     "TRAJLAB_HEARTBEAT_INTERVAL_S": "0.5", "TRAJLAB_STALE_AFTER_S": "15",
                     "TRAJLAB_REAPER_INTERVAL_S": "1", "TRAJLAB_REPUBLISH_AFTER_S": "3",
                     "TRAJLAB_DB_RETRY_MAX_S": "2", **(overrides or {})}
        self.env = {**os.environ, **overrides, "PYTHONPATH": str(ROOT)}
        self.settings = Settings(**{k.removeprefix("TRAJLAB_").lower(): v for k, v in overrides.items()})
        upgrade(pg.url)
        self.client = TestClient(create_app(self.settings))
        self.procs: dict[str, subprocess.Popen] = {}
        self._ready_before: dict[str, int] = {}
        self._n = 0

    def _spawn(self, name: str, cmd: list[str], env: dict | None = None) -> None:
        self.procs[name] = subprocess.Popen(cmd, cwd=ROOT, env={**self.env, **(env or {})},
                                            stdout=open(self.tmp / f"{name}.log", "ab"),
                                            stderr=subprocess.STDOUT, start_new_session=True)

    def start_worker(self, concurrency: int = 2, *, name: str = "worker", env: dict | None = None,
                     prefix: tuple[str, ...] = ()) -> None:
        """``trajlab worker`` as an operator starts it: a pool of ``concurrency`` for both queues and one
        process reserved for quick jobs (app.cli.pools); ``prefix`` runs it elsewhere (``ip netns exec``)."""
        self._n += 1
        self._ready_before[name] = self._ready_lines(name)  # a restarted worker appends to its log
        self._spawn(name, [*prefix, sys.executable, "-m", "app.cli.commands", "worker", "--loglevel=INFO",
                           "--name", f"fault{self._n}@%h"],
                    env={"TRAJLAB_WORKER_CONCURRENCY": str(concurrency), "TRAJLAB_QUICK_CONCURRENCY": "1", **(env or {})})

    def wait_ready(self, name: str = "worker", *, pools: int = 2, timeout: float = 300) -> float:
        """Wait until ``pools`` Celery pools of worker ``name`` logged ``ready.`` (its start, a minute at load
        14, is no part of a recovery being timed); the seconds it took."""
        t0, log = time.monotonic(), self.tmp / f"{name}.log"
        while self._ready_lines(name) - self._ready_before[name] < pools:
            assert self.procs[name].poll() is None, f"{name} exited: {log}"
            assert time.monotonic() - t0 < timeout, f"{name} not ready within {timeout} s: {log}"
            time.sleep(0.2)
        return time.monotonic() - t0

    def _ready_lines(self, name: str) -> int:
        log = self.tmp / f"{name}.log"
        return log.read_text(errors="replace").count(" ready.") if log.exists() else 0

    def start_recovery(self) -> None:
        self._spawn("recover", [sys.executable, "-m", "app.cli.commands", "recover"])

    def kill(self, name: str) -> None:
        proc = self.procs.pop(name, None)
        if proc is not None and proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)

    def stop(self, name: str) -> None:
        stop_group(self.procs.pop(name, None))

    def close(self) -> None:
        # Teardown is no part of a scenario and the servers go right after: SIGKILL, not the warm shutdown
        # SIGTERM asks for (9 s a stack with a worker and recovery at load 13, against 0.1 s; a test that
        # means a graceful stop calls stop() itself)
        for name in list(self.procs):
            self.kill(name)
        self.client.close()
        self.client.app.state.db.dispose()

    # --- what the tests assert -------------------------------------------------------------
    def submit(self, body: dict = QUICK):
        return self.client.post("/v1/jobs", json=body)

    def statuses(self, ids: list[str]) -> dict[str, dict]:
        """The jobs among ``ids`` as the API lists them (one request per 500 jobs, not one per job)."""
        wanted, out, offset = set(ids), {}, 0
        while True:
            r = self.client.get("/v1/jobs", params={"limit": 500, "offset": offset})
            if r.status_code != 200:
                return out
            page = r.json()["items"]
            out.update({j["id"]: j for j in page if j["id"] in wanted})
            if len(page) < 500:
                return out
            offset += 500

    def wait_final(self, ids: list[str], timeout: float) -> tuple[dict[str, dict], float]:
        """Every job final (or the timeout); the jobs and the seconds it took."""
        t0 = time.monotonic()
        while True:
            jobs = self.statuses(ids)
            if len(jobs) == len(ids) and all(j["status"] in FINAL for j in jobs.values()):
                return jobs, time.monotonic() - t0
            if time.monotonic() - t0 > timeout:
                return jobs, time.monotonic() - t0
            time.sleep(0.25)

    def outcome(self, accepted: list[str], timeout: float = 180) -> tuple[dict, list[str], list[str]]:
        """Wait for every accepted job; ``(jobs, lost, run_twice)``: not succeeded, started more than once."""
        jobs, _ = self.wait_final(accepted, timeout=timeout)
        executions = self.executions()
        lost = [j for j in accepted if jobs.get(j, {}).get("status") != "succeeded"]
        return jobs, lost, [j for j in accepted if executions[j] > 1]

    def executions(self) -> Counter:
        """How many times each job was started by a worker, from the worker logs."""
        count: Counter = Counter()
        for log in self.tmp.glob("worker*.log"):
            for m in re.finditer(r"job ([0-9a-f]{32}) attempt \d+ started", log.read_text(errors="replace")):
                count[m.group(1)] += 1
        return count


@pytest.fixture
def stack(tmp_path):
    pg = PostgresServer().start()
    redis = RedisServer(tmp_path).start()
    s = Stack(pg, redis, tmp_path)
    try:
        yield s
    finally:
        s.close()
        redis.kill()
        pg.destroy()


@contextmanager
def namespaced_stack(tmp_path: Path, links: dict[str, list[int]],
                     serve: tuple[int, ...] | None = None) -> Iterator[tuple[Stack, dict[str, Host]]]:
    """Hosts in network namespaces (``links``: host name -> its link numbers) and a stack whose PostgreSQL
    and Redis listen on this side of the links ``serve`` names (default: all); everything removed
    afterwards, also when the test fails."""
    hosts = {name: Host(name, host_links) for name, host_links in links.items()}
    try:
        for h in hosts.values():
            h.create()
        served = serve if serve is not None else tuple(n for host_links in links.values() for n in host_links)
        listen = ("127.0.0.1", *(Host.server_address(n) for n in served))
        pg = PostgresServer(listen=listen).start()
        redis = RedisServer(tmp_path, listen=listen).start()
        stack = Stack(pg, redis, tmp_path)
        try:
            yield stack, hosts
        finally:
            stack.close()
            redis.kill()
            pg.destroy()
    finally:
        for h in hosts.values():
            h.close()


def report(name: str, **figures) -> None:
    """The figures of a fault run, printed for the closing note (pytest -s shows them)."""
    print(f"\nFAULT {name}: " + ", ".join(f"{k}={v:.1f}" if isinstance(v, float) else f"{k}={v}"
                                          for k, v in figures.items()))
