"""Every documented way of running a worker or the API restarts it when it dies (issue 27): compose's
restart policy, the systemd units in deploy/systemd (Restart=always, no start limit), and ``trajlab
worker`` itself, which starts a pool that died again with backoff (app.cli.pools.run_pools).  The
embedded supervisor of ``trajlab serve`` has its own test (tests/unit/test_embedded_supervisor.py)."""
from __future__ import annotations

import configparser
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import yaml

from app.cli.commands import main

ROOT = Path(__file__).resolve().parents[2]
UNITS = ROOT / "deploy" / "systemd"


def _unit(name: str) -> configparser.ConfigParser:
    unit = configparser.ConfigParser(strict=False, interpolation=None)
    unit.optionxform = str
    unit.read(UNITS / name)
    return unit


def test_systemd_units_restart_always_and_run_trajlab_commands(tmp_path):
    for name, command in (("trajlab-worker.service", "worker"), ("trajlab-api.service", "api")):
        unit = _unit(name)
        assert unit["Service"]["Restart"] == "always", name
        assert unit["Unit"]["StartLimitIntervalSec"] == "0", name  # systemd never stops restarting it
        assert unit["Service"]["KillMode"] == "mixed", name  # SIGTERM to trajlab alone: a warm shutdown
        exec_start = unit["Service"]["ExecStart"].split()
        assert exec_start[0].endswith("/bin/trajlab") and exec_start[1] == command, exec_start
        # the subcommand and its options parse (--help exits 0 before anything starts)
        with pytest.raises(SystemExit) as done:
            main([*exec_start[1:], "--help"])
        assert done.value.code == 0
        analyze = shutil.which("systemd-analyze")
        if analyze:  # systemd's own parser, on a copy that runs this checkout's trajlab
            copy = tmp_path / name
            copy.write_text((UNITS / name).read_text().replace(exec_start[0], str(Path(sys.executable).parent / "trajlab")))
            out = subprocess.run([analyze, "verify", str(copy)], capture_output=True, text=True, timeout=60)
            assert out.returncode == 0 and name not in out.stderr, out.stderr


def test_compose_restarts_every_long_running_service():
    services = yaml.safe_load((ROOT / "docker-compose.yml").read_text())["services"]
    long_running = {name: svc for name, svc in services.items() if name != "migrate"}
    assert {"api", "worker", "worker-heavy", "recover"} <= set(long_running)
    for name, svc in long_running.items():
        assert svc.get("restart") in ("always", "unless-stopped"), name


POOL = textwrap.dedent("""
    import os, pathlib, signal, sys, time
    count = pathlib.Path(sys.argv[1])
    n = int(count.read_text()) if count.exists() else 0
    count.write_text(str(n + 1))
    count.with_suffix(".pid").write_text(str(os.getpid()))
    if n < int(sys.argv[2]):
        sys.exit(3)  # a crash on start, as Celery's "Unrecoverable error" is
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    time.sleep(120)
""")
RUN = ("import sys; from app.cli.pools import run_pools; "
       "sys.exit(run_pools({{'a': {a}, 'b': {b}}}, backoff_max_s=0.4, healthy_after_s=60))")


def _start(tmp_path, *, a_crashes: int, b_crashes: int) -> subprocess.Popen:
    (tmp_path / "pool.py").write_text(POOL)
    pool = [sys.executable, str(tmp_path / "pool.py")]
    return subprocess.Popen([sys.executable, "-c", RUN.format(a=[*pool, str(tmp_path / "a"), str(a_crashes)],
                                                              b=[*pool, str(tmp_path / "b"), str(b_crashes)])],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _wait_for(path: Path, value: str, proc: subprocess.Popen, timeout: float = 30) -> None:
    deadline = time.monotonic() + timeout
    while not (path.exists() and path.read_text() == value):
        assert proc.poll() is None, proc.stdout.read()
        assert time.monotonic() < deadline, f"{path.name} never reached {value}"
        time.sleep(0.05)


def test_trajlab_worker_starts_a_dead_pool_again_and_stops_on_sigterm(tmp_path):
    worker = _start(tmp_path, a_crashes=3, b_crashes=0)
    try:
        _wait_for(tmp_path / "a", "4", worker)  # three crashes, then a fourth start that stays up
        assert (tmp_path / "b").read_text() == "1"  # the other pool was left alone
        time.sleep(0.3)
        assert worker.poll() is None
        worker.send_signal(signal.SIGTERM)
        assert worker.wait(timeout=30) == 0
        assert worker.stdout.read().count("exited with 3; starting it again") == 3
    finally:
        if worker.poll() is None:
            worker.kill()


def test_a_pool_that_exits_cleanly_stops_the_worker(tmp_path):
    worker = _start(tmp_path, a_crashes=0, b_crashes=0)
    try:
        _wait_for(tmp_path / "a", "1", worker)
        _wait_for(tmp_path / "b", "1", worker)
        os.kill(int((tmp_path / "b.pid").read_text()), signal.SIGTERM)  # pool b ends by itself, status 0
        assert worker.wait(timeout=30) == 0
    finally:
        if worker.poll() is None:
            worker.kill()
