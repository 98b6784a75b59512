"""A production-shaped trajlab for the observability tests: ``trajlab api`` with 2 processes on a free port,
a Celery worker and ``trajlab recover``, all as subprocesses with JSON logs, on a PostgreSQL database and
a Redis database of their own (so the counts are this stack's alone), and Debian's Prometheus scraping it.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path

import httpx
import psycopg

from app.api.auth import create_key
from app.runtime.db import get_database
from app.runtime.migrate import upgrade
from app.service.broker import QUEUES
from tests.integration.conftest import PG_ADMIN_URL, REDIS_URL, ROOT, claim_redis_db


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until(check, *, timeout: float, what: str, interval: float = 0.25):
    deadline = time.monotonic() + timeout
    last = None
    while time.monotonic() < deadline:
        try:
            last = check()
            if last:
                return last
        except (httpx.HTTPError, OSError, ValueError) as exc:
            last = exc
        time.sleep(interval)
    raise AssertionError(f"{what}: not after {timeout} s (last: {last!r})")


def json_lines(path: Path) -> list[dict]:
    """The JSON objects of a log file (Celery's banner and other plain lines are skipped)."""
    out = []
    for line in path.read_text(errors="replace").splitlines():
        if line.startswith("{"):
            try:
                out.append(json.loads(line))
            except ValueError:
                pass
    return out


class OpsStack:
    def __init__(self, workdir: Path):
        self.dir = workdir
        self.procs: list[subprocess.Popen] = []
        self.db_name = f"trajlab_ops_{uuid.uuid4().hex[:10]}"
        self.redis, self.redis_url = claim_redis_db(REDIS_URL)
        base = PG_ADMIN_URL.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1)
        self.db_url = f"{base}/{self.db_name}"
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"

    def _spawn(self, name: str, cmd: list[str], env: dict) -> None:
        log = open(self.dir / f"{name}.log", "wb")
        self.procs.append(subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT,
                                           start_new_session=True))

    def start(self) -> None:
        with psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5) as admin:
            admin.execute(f'CREATE DATABASE "{self.db_name}"')
        upgrade(self.db_url)
        db = get_database(self.db_url)
        _, self.admin_key = create_key(db, name="ops-admin", admin=True)
        _, self.user_key = create_key(db, name="ops-user", owner="someone")
        db.dispose()
        env = {**os.environ, "PYTHONPATH": str(ROOT), "TRAJLAB_DATABASE_URL": self.db_url,
               "TRAJLAB_BROKER_URL": self.redis_url, "TRAJLAB_AUTH": "required", "TRAJLAB_LOG_FORMAT": "json",
               "TRAJLAB_API_WORKERS": "2", "TRAJLAB_HEARTBEAT_INTERVAL_S": "0.5", "TRAJLAB_REAPER_INTERVAL_S": "1"}
        env.pop("PROMETHEUS_MULTIPROC_DIR", None)  # `trajlab api` makes its own
        self._spawn("api", [sys.executable, "-m", "app.cli.commands", "api", "--host", "127.0.0.1",
                            "--port", str(self.port)], env)
        self._spawn("worker", [sys.executable, "-m", "celery", "-A", "worker.celery_app:celery_app", "worker",
                               "--loglevel=INFO", "--concurrency=1", "-n", f"ops-{uuid.uuid4().hex[:6]}@%h",
                               "-Q", ",".join(QUEUES)], env)
        self._spawn("recover", [sys.executable, "-m", "app.cli.commands", "recover"], env)
        wait_until(lambda: httpx.get(f"{self.url}/healthz", timeout=2).status_code == 200, timeout=60,
                   what=f"trajlab api on {self.url} (log {self.dir / 'api.log'})")

    def start_prometheus(self) -> None:
        """Debian's Prometheus on a free port, its own config and data directory, scraping every second
        with the admin key."""
        binary = shutil.which("prometheus")
        assert binary, "Debian's prometheus is missing: scripts/test-prerequisites.sh installs it"
        self.prom_port = free_port()
        self.prom_url = f"http://127.0.0.1:{self.prom_port}"
        config = self.dir / "prometheus.yml"
        config.write_text(json.dumps({  # YAML is a superset of JSON
            "global": {"scrape_interval": "1s", "evaluation_interval": "1s"},
            "scrape_configs": [{"job_name": "trajlab", "static_configs": [{"targets": [f"127.0.0.1:{self.port}"]}],
                                "authorization": {"type": "Bearer", "credentials": self.admin_key}}]}))
        self._spawn("prometheus", [binary, f"--config.file={config}", f"--storage.tsdb.path={self.dir / 'tsdb'}",
                                   f"--web.listen-address=127.0.0.1:{self.prom_port}"], dict(os.environ))
        wait_until(lambda: httpx.get(f"{self.prom_url}/-/ready", timeout=2).status_code == 200, timeout=60,
                   what=f"Prometheus on {self.prom_url} (log {self.dir / 'prometheus.log'})")

    def query(self, expr: str) -> list[dict]:
        r = httpx.get(f"{self.prom_url}/api/v1/query", params={"query": expr}, timeout=10)
        r.raise_for_status()
        return r.json()["data"]["result"]

    def value(self, expr: str) -> float | None:
        result = self.query(expr)
        return float(result[0]["value"][1]) if result else None

    def stop(self) -> None:
        for proc in reversed(self.procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in self.procs:
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)
        self.redis.flushdb()
        with psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{self.db_name}" WITH (FORCE)')
