"""``trajlab serve`` as a newcomer runs it: the embedded Redis is supervised, nothing outlives serve,
and a taken port is one line before anything starts."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from tests.faults.conftest import QUICK, report
from tests.integration.live import free_port
from tests.support import wait_serving

pytestmark = [pytest.mark.integration, pytest.mark.faults]
ROOT = Path(__file__).resolve().parents[2]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except OSError:
        return False
    try:  # a zombie is dead too
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except OSError:
        return False


def _descendants(pid: int) -> set[int]:
    out = subprocess.run(["ps", "-e", "-o", "pid=,ppid="], capture_output=True, text=True).stdout.split()
    pairs = [(int(a), int(b)) for a, b in zip(out[::2], out[1::2])]
    found, frontier = set(), {pid}
    while frontier:
        frontier = {c for c, p in pairs if p in frontier} - found
        found |= frontier
    return found


def _serve(data: Path, port: int) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k not in ("TRAJLAB_BROKER_URL", "TRAJLAB_DATABASE_URL")}
    env.update({"TRAJLAB_DATA_DIR": str(data), "TRAJLAB_REAPER_INTERVAL_S": "1", "TRAJLAB_REPUBLISH_AFTER_S": "2",
                "PYTHONPATH": str(ROOT)})
    return subprocess.Popen([sys.executable, "-m", "app.cli.commands", "serve", "--port", str(port)], cwd=ROOT, env=env,
                            stdout=open(data.parent / "serve.log", "ab"), stderr=subprocess.STDOUT)


def _wait_up(url: str, proc: subprocess.Popen) -> None:
    wait_serving(url + "/healthz", proc=proc, what="trajlab serve", status=200)


def _run_jobs(url: str, n: int, timeout: float = 120) -> list[dict]:
    ids = []
    for _ in range(n):
        r = httpx.post(url + "/v1/jobs", json=QUICK, timeout=10)
        assert r.status_code == 202, r.text
        ids.append(r.json()["id"])
    deadline = time.monotonic() + timeout
    while True:
        jobs = [httpx.get(f"{url}/v1/jobs/{i}", timeout=10).json() for i in ids]
        if all(j["status"] in ("succeeded", "failed", "cancelled") for j in jobs):
            return jobs
        assert time.monotonic() < deadline, [j["status"] for j in jobs]
        time.sleep(0.2)


def test_a_taken_port_is_one_line_and_nothing_starts(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        data = tmp_path / "data"
        env = {**os.environ, "TRAJLAB_DATA_DIR": str(data)}
        p = subprocess.run([sys.executable, "-m", "app.cli.commands", "serve", "--port", str(port)], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and f"port {port}" in lines[0] and "make run PORT=" in lines[0], p.stderr
    assert not (data / "redis.pid").exists() and not (data / "worker.log").exists()


def test_embedded_redis_killed_then_sigint_leaves_nothing_running(tmp_path):
    data, port = tmp_path / "data", free_port()
    url = f"http://127.0.0.1:{port}"
    proc = _serve(data, port)
    try:
        _wait_up(url, proc)
        assert [j["status"] for j in _run_jobs(url, 3)] == ["succeeded"] * 3
        redis_pid = int((data / "redis.pid").read_text())
        os.kill(redis_pid, signal.SIGKILL)  # the embedded Redis dies
        killed = time.monotonic()
        jobs = _run_jobs(url, 10)  # accepted while it is down or restarting; run once it is back
        recovery_s = time.monotonic() - killed
        new_pid = int((data / "redis.pid").read_text())
        report("embedded-redis-killed", accepted=10, finished=sum(j["status"] == "succeeded" for j in jobs),
               lost=sum(j["status"] != "succeeded" for j in jobs), recovery_s=recovery_s)
        assert new_pid != redis_pid and _alive(new_pid)
        assert [j["status"] for j in jobs] == ["succeeded"] * 10 and all(j["attempts"] == 1 for j in jobs)
        children = _descendants(proc.pid)
        assert new_pid in children and len(children) >= 3  # redis, the worker and its pool
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=60)
    deadline = time.monotonic() + 30
    while any(_alive(c) for c in children) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [c for c in children if _alive(c)]
    assert (data / "redis.rdb").exists() and (data / "trajlab.db").exists()  # SHUTDOWN SAVE wrote the dump


def test_sigkill_of_serve_takes_its_children_with_it(tmp_path):
    data, port = tmp_path / "data", free_port()
    proc = _serve(data, port)
    try:
        _wait_up(f"http://127.0.0.1:{port}", proc)
        children = _descendants(proc.pid)
        assert children
    finally:
        proc.kill()
        proc.wait(timeout=30)
    deadline = time.monotonic() + 60
    while any(_alive(c) for c in children) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [c for c in children if _alive(c)]
