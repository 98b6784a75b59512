"""A full disk loses nothing: PostgreSQL with its data directory on a small tmpfs, and ``trajlab serve`` with its
SQLite database and its data directory (Redis dump, logs) each on one, filled to the last block during a burst
of submissions and freed again.  A submission during the fault is a 503 with Retry-After or is accepted and
run; every accepted job succeeds; the service comes back by itself once the space returns, and /readyz names
the full part while it lasts.  The tests mount filesystems, so they run as root (CI does) and fail otherwise.
"""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import pytest

from tests.faults.conftest import FINAL, QUICK, Stack, report
from tests.faults.disk import Filler, tmpfs
from tests.faults.servers import PostgresServer, RedisServer
from tests.integration.live import free_port

pytestmark = [pytest.mark.integration, pytest.mark.faults]
ROOT = Path(__file__).resolve().parents[2]


class Burst(threading.Thread):
    """Submits quick jobs every ``interval_s`` through ``post`` until stopped; every answer with its time."""

    def __init__(self, post, interval_s: float = 0.05):
        super().__init__(daemon=True)
        self.post, self.interval_s = post, interval_s
        self.answers: list[tuple[float, int, str | None, str | None]] = []  # (t, status, Retry-After, job id)
        self._halt = threading.Event()

    def run(self) -> None:
        while not self._halt.wait(self.interval_s):
            try:
                r = self.post()
            except httpx.HTTPError:
                self.answers.append((time.monotonic(), 0, None, None))  # no answer at all: counted, asserted on
                continue
            self.answers.append((time.monotonic(), r.status_code, r.headers.get("Retry-After"),
                                 r.json().get("id") if r.status_code == 202 else None))

    def stop(self) -> "Burst":
        self._halt.set()
        self.join(timeout=60)
        return self

    @property
    def accepted(self) -> list[str]:
        return [i for _, code, _, i in self.answers if code == 202]

    def check(self) -> int:
        """Only 202s and 503s with Retry-After; the number of 503s."""
        odd = [(code, ra) for _, code, ra, _ in self.answers if code != 202 and not (code == 503 and ra)]
        assert not odd, f"answers other than 202 or 503 with Retry-After: {odd[:10]}"
        return sum(code == 503 for _, code, _, _ in self.answers)


def _wait(predicate, timeout: float, what: str) -> float:
    t0 = time.monotonic()
    while not predicate():
        assert time.monotonic() - t0 < timeout, f"{what} within {timeout} s"
        time.sleep(0.2)
    return time.monotonic() - t0


# ----------------------------------------------------------------------------------------- PostgreSQL
def test_postgres_on_a_full_disk_loses_nothing(tmp_path):
    with tmpfs(128, owner="postgres") as disk:
        pg = PostgresServer(root=disk).start()
        redis = RedisServer(tmp_path).start()
        stack = Stack(pg, redis, tmp_path)
        filler = Filler(disk)
        try:
            # one solver process (no reserved quick pool): warmed by the first job, so the figures are the fault's
            stack.start_worker(concurrency=1, env={"TRAJLAB_QUICK_CONCURRENCY": "0"})
            stack.start_recovery()
            first = stack.submit().json()["id"]
            _wait(lambda: stack.statuses([first]).get(first, {}).get("status") in FINAL, 180, "the first job done")
            burst = Burst(stack.submit, interval_s=0.1)
            burst.start()
            time.sleep(1)
            filler.fill()
            full_at = time.monotonic()
            time.sleep(5)
            filler.free()
            freed_at = time.monotonic()
            time.sleep(2)
            burst.stop()
            refused = burst.check()
            accepted = burst.accepted
            jobs, lost, twice = stack.outcome(accepted, timeout=60)  # the stated bound after the space returns
            done_s = max(time.monotonic() - freed_at, 0.0)
            during = [a for a in burst.answers if full_at <= a[0] <= freed_at]
            first_ok = next((t for t, code, _, _ in burst.answers if t > freed_at and code == 202), None)
            report("full-disk-postgres", accepted=len(accepted), refused=refused,
                   refused_during=sum(a[1] == 503 for a in during), accepted_during=sum(a[1] == 202 for a in during),
                   lost=len(lost), run_twice=len(twice),
                   accepting_again_s=(first_ok - freed_at) if first_ok else -1.0, all_done_after_free_s=done_s)
            assert not lost, {j: jobs.get(j, {}).get("status") for j in lost[:10]}
            assert first_ok is not None, "no submission was accepted after the space returned"
            assert any(a[1] == 503 for a in during) or _stores_retried(tmp_path), \
                "the full disk refused nothing: the test did not fill it"
            for job_id in accepted[:: max(1, len(accepted) // 20)]:  # stored whole: results read back
                assert stack.client.get(f"/v1/jobs/{job_id}/result").status_code == 200
        finally:
            filler.free()
            stack.close()
            redis.kill()
            if (disk / "pg.log").exists():  # the server's own account of the fault, kept beside the others
                (tmp_path / "pg.log").write_bytes((disk / "pg.log").read_bytes())
            pg.destroy()


def _stores_retried(tmp: Path) -> bool:
    return any("DiskFull" in log.read_text(errors="replace") for log in tmp.glob("worker*.log"))


# ----------------------------------------------------------------------------------------- embedded
def _serve(data: Path, db: Path, port: int, log: Path) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k not in ("TRAJLAB_BROKER_URL", "TRAJLAB_DATABASE_URL")}
    env.update({"TRAJLAB_DATA_DIR": str(data), "TRAJLAB_DATABASE_URL": f"sqlite:///{db / 'trajlab.db'}",
                "TRAJLAB_REAPER_INTERVAL_S": "1", "TRAJLAB_REPUBLISH_AFTER_S": "2", "TRAJLAB_STALE_AFTER_S": "15",
                "TRAJLAB_HEARTBEAT_INTERVAL_S": "0.5", "TRAJLAB_MIN_FREE_DISK_MB": "2", "PYTHONPATH": str(ROOT),
                # one solver process, warmed by the first job: the figures are the fault's, not a cold start's
                "TRAJLAB_WORKER_CONCURRENCY": "1", "TRAJLAB_QUICK_CONCURRENCY": "0"})
    return subprocess.Popen([sys.executable, "-m", "app.cli.commands", "serve", "--port", str(port)], cwd=ROOT,
                            env=env, stdout=open(log, "ab"), stderr=subprocess.STDOUT, start_new_session=True)


class Embedded:
    def __init__(self, url: str):
        self.http = httpx.Client(base_url=url, timeout=30)

    def post(self):
        return self.http.post("/v1/jobs", json=QUICK)

    def statuses(self, ids: list[str]) -> dict[str, str]:
        items = self.http.get("/v1/jobs", params={"limit": 500}).json()["items"]
        wanted = set(ids)
        return {j["id"]: j["status"] for j in items if j["id"] in wanted}

    def all_final(self, ids: list[str]) -> bool:
        found = self.statuses(ids)
        return len(found) == len(set(ids)) and all(s in FINAL for s in found.values())

    def ready(self) -> dict:
        r = self.http.get("/readyz")
        return {"code": r.status_code, **r.json()}


def _phase(api: Embedded, filler: Filler, during) -> tuple[Burst, float, float]:
    """A burst; the filesystem filled for 5 s in it (``during`` runs while full), then freed. Returns the
    burst, when it was freed, and how long every accepted job took to finish after that."""
    burst = Burst(api.post, interval_s=0.1)
    burst.start()
    time.sleep(1)
    filler.fill()
    during()
    filler.free()
    freed_at = time.monotonic()
    time.sleep(2)
    burst.stop()
    # the stated bound: every job accepted in the fault is final within 60 s of the space returning
    return burst, freed_at, _wait(lambda: api.all_final(burst.accepted), 60, "every accepted job final")


def test_embedded_database_and_data_directory_full(tmp_path):
    port = free_port()
    with tmpfs(48) as data, tmpfs(48) as db:
        proc = _serve(data, db, port, tmp_path / "serve.log")
        api = Embedded(f"http://127.0.0.1:{port}")
        try:
            _wait(lambda: proc.poll() is None and _up(api), 90, "trajlab serve up")
            first = api.post().json()["id"]
            _wait(lambda: api.all_final([first]), 180, "the first job done")

            # (b) the SQLite database's filesystem full: submissions 503 with Retry-After, /readyz names it
            seen: dict[str, dict] = {}

            def db_full():
                time.sleep(1)
                seen["b"] = api.ready()
                time.sleep(4)
            burst_b, _, done_b = _phase(api, Filler(db), db_full)
            refused_b = burst_b.check()
            assert seen["b"]["code"] == 503 and seen["b"]["database_storage"].startswith("full"), seen["b"]

            # (c) the data directory full (Redis dump, logs): the dump fails, Redis still takes writes, jobs run
            import redis as redis_lib

            broker = redis_lib.Redis(unix_socket_path=str(data / "redis.socket"), socket_timeout=10)

            def data_full():
                broker.bgsave()  # the periodic dump, now: it cannot be written
                _wait(lambda: broker.info("persistence")["rdb_bgsave_in_progress"] == 0, 30, "the dump ended")
                seen["dump"] = broker.info("persistence")["rdb_last_bgsave_status"]
                seen["c"] = api.ready()
                job = api.post()
                assert job.status_code == 202, job.text  # accepted and run while the directory is full
                seen["run_while_full_s"] = _wait(lambda: api.all_final([job.json()["id"]]), 30, "a job run while full")
                # its plots render (the renderings are cached in the API process's memory, not in the directory)
                png = api.http.get(api.http.get(f"/v1/jobs/{job.json()['id']}/plots").json()["plots"][0]["png"])
                seen["plot"] = (png.status_code, png.content[:4])
            burst_c, _, done_c = _phase(api, Filler(data), data_full)
            refused_c = burst_c.check()
            assert seen["dump"] == "err", "the dump did not fail: the data directory was not full"
            assert seen["c"]["code"] == 503 and seen["c"]["data_dir"].startswith("full"), seen["c"]
            assert seen["c"]["broker"] == "up", seen["c"]  # a failed dump does not refuse writes
            assert refused_c == 0
            assert seen["plot"] == (200, b"\x89PNG"), seen["plot"]

            accepted = burst_b.accepted + burst_c.accepted + [first]
            final = api.statuses(accepted)
            lost = [j for j in accepted if final.get(j) != "succeeded"]
            back = _wait(lambda: _ready_parts(api), 60, "/readyz back")
            report("full-disk-embedded-sqlite", accepted=len(burst_b.accepted), refused=refused_b,
                   all_done_after_free_s=done_b)
            report("full-disk-embedded-data-dir", accepted=len(burst_c.accepted), refused=refused_c,
                   job_run_while_full_s=seen["run_while_full_s"], all_done_after_free_s=done_c)
            report("full-disk-embedded", lost=len(lost), readyz_back_s=back)
            assert not lost, {j: final.get(j) for j in lost[:10]}
            serve_log = (tmp_path / "serve.log").read_text(errors="replace").splitlines()
            crashes = [line for line in serve_log if " exited with " in line]
            assert not crashes, crashes  # neither Redis nor the worker died of the full disks
        finally:
            proc.send_signal(2)  # SIGINT: serve stops its worker and Redis
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, 9)
                proc.wait(timeout=30)


def _up(api: Embedded) -> bool:
    try:
        return api.http.get("/healthz", timeout=2).status_code == 200
    except httpx.HTTPError:
        return False


def _ready_parts(api: Embedded) -> bool:
    body = api.ready()
    return all(body.get(p) == "up" for p in ("database", "broker", "database_storage", "data_dir"))
