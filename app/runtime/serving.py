"""``trajlab api`` with several processes: uvicorn's supervisor, each process accepting on a socket of its own.

uvicorn's workers share one listening socket, and the process that wakes first
accepts every pending connection (uvloop drains the backlog in one go): at 100
``wrk`` connections one of 2 processes held 89 of them and the other 11, so the
busy one queued and the idle one idled (benchmarks/api_load.py).  With
``SO_REUSEPORT`` each process listens on a socket of its own on the same port,
and the kernel spreads new connections over them by a hash of the addresses.

The parent binds the port with ``SO_REUSEPORT`` and never listens on it: it only
reserves the port (and resolves port 0), so no connection waits on a socket that
nobody accepts from.  Everything else (health checks, restarting a dead process,
signals) is uvicorn's own ``Multiprocess`` supervisor; a replaced process opens
its own socket again.
"""
from __future__ import annotations

import socket

from uvicorn import Config
from uvicorn.supervisors import multiprocess


def reuseport_socket(host: str, port: int) -> socket.socket:
    """A TCP socket bound to ``(host, port)`` with ``SO_REUSEPORT`` (not listening yet)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    sock.bind((host, port))
    sock.set_inheritable(True)
    return sock


class ReusePortProcess(multiprocess.Process):
    """uvicorn's worker process, serving on a listening socket of its own instead of the parent's."""

    def target(self, sockets=None) -> None:  # runs in the child
        super().target([reuseport_socket(self.config.host, self.config.port)])


def run_processes(config: Config) -> None:
    """Serve ``config.workers`` processes on ``config.host:config.port`` until SIGINT/SIGTERM."""
    reserved = reuseport_socket(config.host, config.port)
    config.port = reserved.getsockname()[1]
    # The supervisor creates its processes through this module's global (in init_processes, restarts and
    # keep_subprocess_alive alike); this parent does nothing else, and the children are spawned afresh.
    multiprocess.Process = ReusePortProcess  # type: ignore[misc]  # a class replaced on purpose
    try:
        multiprocess.Multiprocess(config, sockets=[reserved]).run()
    finally:
        reserved.close()
