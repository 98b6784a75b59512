"""Integration fixtures: real PostgreSQL, real Redis, a real Celery worker process.

``service`` creates a fresh PostgreSQL database and migrates it, takes a Redis
database no other test run holds (so two runs on one machine cannot collide), starts ``celery worker`` and ``trajlab recover`` as subprocesses with fast
heartbeat/recovery settings, and serves the app through TestClient.  If PostgreSQL
or Redis is unreachable the run stops with a message naming it and how to start it.
"""
from __future__ import annotations

import atexit
import os
import random
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import psycopg
import pytest
import redis
from fastapi.testclient import TestClient

from app.service.broker import QUEUES
from app.api.main import create_app
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
PG_ADMIN_URL = os.environ.get("TRAJLAB_TEST_PG_ADMIN", "postgresql://postgres@127.0.0.1:5432/test")
REDIS_URL = os.environ.get("TRAJLAB_TEST_REDIS", "redis://127.0.0.1:6379/11")

START_HINTS = {
    "PostgreSQL": "pg_ctlcluster --skip-systemctl-redirect $(ls /etc/postgresql) main start",
    "Redis": 'redis-server --daemonize yes --bind 127.0.0.1 -::1 --port 6379 --save "" --appendonly no',
}


def _unreachable(name: str, url: str, exc: Exception) -> None:
    pytest.exit(f"{name} is unreachable at {url} ({type(exc).__name__}: {exc}). "
                f"Integration tests need a real {name}; start it with: {START_HINTS[name]}", returncode=3)


@pytest.fixture(scope="session")
def pg_url():
    try:
        admin = psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5)
    except Exception as exc:
        _unreachable("PostgreSQL", PG_ADMIN_URL, exc)
    name = f"trajlab_it_{uuid.uuid4().hex[:10]}"
    admin.execute(f'CREATE DATABASE "{name}"')
    base = PG_ADMIN_URL.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1)
    yield f"{base}/{name}"
    admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
    admin.close()


RUN_LOCK_KEY = "trajlab:test-run-lock"
# A claim lives as long as the process that holds it: renewed every RUN_LOCK_RENEW_S, released at exit,
# and a killed run's claims lapse after RUN_LOCK_TTL_S (a four-hour lock left by killed runs once held
# all fifteen databases and the next run could claim none).
RUN_LOCK_TTL_S = 300
RUN_LOCK_RENEW_S = 30
_RENEW = "if redis.call('GET', KEYS[1]) == ARGV[1] then return redis.call('EXPIRE', KEYS[1], ARGV[2]) end return 0"
_RELEASE = "if redis.call('GET', KEYS[1]) == ARGV[1] then return redis.call('DEL', KEYS[1]) end return 0"
_claims: dict[str, tuple[redis.Redis, str]] = {}   # url -> (client, token), this process's live claims
_claims_lock = threading.Lock()
_renewer: threading.Thread | None = None


def _renew_claims() -> None:
    while True:
        time.sleep(RUN_LOCK_RENEW_S)
        with _claims_lock:
            held = list(_claims.items())
        for url, (r, token) in held:
            try:
                if not r.eval(_RENEW, 1, RUN_LOCK_KEY, token, RUN_LOCK_TTL_S):
                    with _claims_lock:
                        _claims.pop(url, None)   # released (flushdb) or lapsed: nothing left to hold
            except redis.RedisError:
                pass   # a test that stops Redis on purpose; the next round tries again


def release_redis_dbs() -> None:
    """Give back every database this process still holds (run at exit)."""
    with _claims_lock:
        held = list(_claims.values())
        _claims.clear()
    for r, token in held:
        try:
            r.eval(_RELEASE, 1, RUN_LOCK_KEY, token)
        except redis.RedisError:
            pass


atexit.register(release_redis_dbs)


def claim_redis_db(base_url: str) -> tuple[redis.Redis, str]:
    """A Redis database of its own for this test run (1-15, not the shared 0).

    Two runs on one machine must not flush each other's queue: a run takes a
    database whose lock key it can set with NX, and flushes only that one. The
    claim is renewed while this process lives and given back when it exits.
    """
    global _renewer
    base = base_url.rsplit("/", 1)[0] if base_url.rsplit("/", 1)[-1].isdigit() else base_url.rstrip("/")
    token = uuid.uuid4().hex
    for db in random.sample(range(1, 16), 15):
        url = f"{base}/{db}"
        r = redis.Redis.from_url(url, socket_connect_timeout=5)
        if r.set(RUN_LOCK_KEY, token, nx=True, ex=RUN_LOCK_TTL_S):
            r.flushdb()
            r.set(RUN_LOCK_KEY, token, ex=RUN_LOCK_TTL_S)
            with _claims_lock:
                _claims[url] = (r, token)
                if _renewer is None:
                    _renewer = threading.Thread(target=_renew_claims, name="redis-claims", daemon=True)
                    _renewer.start()
            return r, url
    raise RuntimeError(f"every Redis database 1-15 at {base} is held by another test run ({RUN_LOCK_KEY})")


@pytest.fixture(scope="session")
def redis_url():
    try:
        redis.Redis.from_url(REDIS_URL, socket_connect_timeout=5).ping()
    except Exception as exc:
        _unreachable("Redis", REDIS_URL, exc)
    r, url = claim_redis_db(REDIS_URL)
    yield url
    r.flushdb()  # also releases the run lock


class Service:
    """A running trajlab: the app under TestClient and one real worker process."""

    def __init__(self, settings: Settings, env: dict, log_dir: Path):
        self.settings = settings
        self.env = env
        self.log_dir = log_dir
        self.worker: subprocess.Popen | None = None
        self.client = TestClient(create_app(settings))
        self._n = 0

    # --- worker process --------------------------------------------------------------
    def start_worker(self, concurrency: int = 2) -> None:
        self._n += 1
        log = open(self.log_dir / f"worker-{self._n}.log", "wb")
        cmd = [sys.executable, "-m", "celery", "-A", "worker.celery_app:celery_app", "worker",
               "--loglevel=INFO", f"--concurrency={concurrency}", "-n", f"it{self._n}-{uuid.uuid4().hex[:6]}@%h",
               "-Q", ",".join(QUEUES)]
        # Own session: kill_worker() can SIGKILL the whole process group, pool children included.
        self.worker = subprocess.Popen(cmd, cwd=ROOT, env=self.env, stdout=log, stderr=subprocess.STDOUT,
                                       start_new_session=True)

    def start_second_worker(self) -> None:
        """Another worker process, for tests that need two workers."""
        log = open(self.log_dir / "worker-second.log", "ab")
        cmd = [sys.executable, "-m", "celery", "-A", "worker.celery_app:celery_app", "worker",
               "--loglevel=INFO", "--concurrency=1", "-n", f"second-{uuid.uuid4().hex[:6]}@%h",
               "-Q", ",".join(QUEUES)]
        self.second = subprocess.Popen(cmd, cwd=ROOT, env=self.env, stdout=log, stderr=subprocess.STDOUT,
                                       start_new_session=True)

    def stop_second_worker(self) -> None:
        if getattr(self, "second", None) is not None and self.second.poll() is None:
            os.killpg(self.second.pid, signal.SIGTERM)
            self.second.wait(timeout=60)
        self.second = None

    # --- the recovery loop (reaper, re-publisher), its own process as in production ------
    def start_recovery(self) -> None:
        log = open(self.log_dir / "recover.log", "ab")
        self.recovery = subprocess.Popen([sys.executable, "-m", "app.cli.commands", "recover"], cwd=ROOT, env=self.env,
                                         stdout=log, stderr=subprocess.STDOUT, start_new_session=True)

    def stop_recovery(self) -> None:
        if getattr(self, "recovery", None) is not None and self.recovery.poll() is None:
            os.killpg(self.recovery.pid, signal.SIGTERM)
            self.recovery.wait(timeout=30)

    def kill_worker(self) -> None:
        if self.worker is not None and self.worker.poll() is None:
            os.killpg(self.worker.pid, signal.SIGKILL)
            self.worker.wait(timeout=30)
        self.worker = None

    def stop_worker(self) -> None:
        if self.worker is not None and self.worker.poll() is None:
            os.killpg(self.worker.pid, signal.SIGTERM)
            try:
                self.worker.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(self.worker.pid, signal.SIGKILL)
                self.worker.wait(timeout=30)
        self.worker = None

    # --- HTTP helpers ----------------------------------------------------------------
    def submit(self, kind: str, preset: str | None = None, params: dict | None = None,
               label: str | None = None, headers: dict | None = None):
        body: dict = {"kind": kind}
        if preset is not None:
            body["preset"] = preset
        if params is not None:
            body["params"] = params
        if label is not None:
            body["label"] = label
        return self.client.post("/v1/jobs", json=body, headers=headers or {})

    def wait(self, job_id: str, timeout: float = 120, until=("succeeded", "failed", "cancelled")) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            job = self.client.get(f"/v1/jobs/{job_id}").json()
            if job["status"] in until:
                return job
            if time.monotonic() > deadline:
                raise AssertionError(f"job {job_id} still {job['status']} after {timeout} s: {job['message']}; "
                                     f"worker logs in {self.log_dir}")
            time.sleep(0.2)

    def result(self, job_id: str) -> dict:
        r = self.client.get(f"/v1/jobs/{job_id}/result")
        assert r.status_code == 200, r.text
        return r.json()


@pytest.fixture(scope="session")
def service(pg_url, redis_url, tmp_path_factory):
    upgrade(pg_url)
    log_dir = tmp_path_factory.mktemp("service")
    overrides = {
        "TRAJLAB_DATABASE_URL": pg_url,
        "TRAJLAB_BROKER_URL": redis_url,
        "TRAJLAB_HEARTBEAT_INTERVAL_S": "0.5",
        "TRAJLAB_STALE_AFTER_S": "5",
        "TRAJLAB_REAPER_INTERVAL_S": "1",
        "TRAJLAB_MAX_ATTEMPTS": "3",
        "TRAJLAB_MONTE_CARLO_CHUNK_SAMPLES": "2000",
    }
    env = {**os.environ, **overrides, "PYTHONPATH": str(ROOT)}
    settings = Settings(**{k.removeprefix("TRAJLAB_").lower(): v for k, v in overrides.items()})
    svc = Service(settings, env, log_dir)
    svc.start_worker()
    svc.start_recovery()
    yield svc
    svc.stop_recovery()
    svc.stop_worker()
    svc.client.close()
    svc.client.app.state.db.dispose()
