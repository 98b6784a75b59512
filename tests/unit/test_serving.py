"""``trajlab api`` with several processes (app.runtime.serving): each process listens on a socket of its own."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from app.runtime.serving import reuseport_socket

ROOT = Path(__file__).resolve().parents[2]


def _listeners(port: int) -> int:
    """Listening TCP sockets on 127.0.0.1:``port`` (state 0A in /proc/net/tcp)."""
    local = f"0100007F:{port:04X}"
    lines = Path("/proc/net/tcp").read_text().splitlines()[1:]
    return sum(1 for line in lines if line.split()[1] == local and line.split()[3] == "0A")


def test_the_kernel_spreads_connections_over_reuseport_listeners():
    # the premise of app.runtime.serving: two listeners on one port both receive connections
    a = reuseport_socket("127.0.0.1", 0)
    port = a.getsockname()[1]
    b = reuseport_socket("127.0.0.1", port)
    clients = []
    try:
        for s in (a, b):
            s.listen(128)
            s.setblocking(False)
        for _ in range(64):
            c = socket.create_connection(("127.0.0.1", port))
            clients.append(c)
        time.sleep(0.2)
        accepted = []
        for s in (a, b):
            n = 0
            while True:
                try:
                    conn, _ = s.accept()
                except BlockingIOError:
                    break
                conn.close()
                n += 1
            accepted.append(n)
        assert sum(accepted) == 64 and min(accepted) >= 10, accepted
    finally:
        for c in clients:
            c.close()
        a.close()
        b.close()


@pytest.mark.slow
def test_trajlab_api_serves_each_process_on_its_own_socket_and_stops_on_sigterm(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**os.environ, "TRAJLAB_API_WORKERS": "2", "TRAJLAB_DATABASE_URL": f"sqlite:///{tmp_path / 'api.db'}",
           "TRAJLAB_DATA_DIR": str(tmp_path), "TRAJLAB_AUTH": "off", "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "app.cli.commands", "api", "--host", "127.0.0.1", "--port", str(port)],
                            env=env, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while _listeners(port) < 2:
            assert proc.poll() is None, "trajlab api exited"
            assert time.monotonic() < deadline, f"{_listeners(port)} listeners after 60 s"
            time.sleep(0.2)
        time.sleep(0.5)
        # two processes, two listening sockets; the parent's (which only reserves the port) is not one
        assert _listeners(port) == 2
        assert urllib.request.urlopen(f"http://127.0.0.1:{port}/healthz", timeout=10).status == 200
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 0
        assert _listeners(port) == 0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
