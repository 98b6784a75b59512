"""Redis and PostgreSQL servers of a fault test's own: free ports, temp directories, stopped and
started at will, and never the machine's shared servers."""
from __future__ import annotations

import atexit
import os
import shutil
import signal
import subprocess
import tempfile
import time
from functools import cache
from pathlib import Path

from tests.integration.live import free_port

PG_BIN = Path("/usr/lib/postgresql/15/bin")


def _as_postgres(cmd: list[str]) -> list[str]:
    # PostgreSQL refuses to run as root: run its tools as the postgres user when we are root
    return ["runuser", "-u", "postgres", "--", *cmd] if os.geteuid() == 0 else cmd


def _wait(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise RuntimeError(f"{what} did not happen within {timeout} s")
        time.sleep(0.05)


class RedisServer:
    """``redis-server`` without persistence on a free port."""

    def __init__(self, tmp: Path, listen: tuple[str, ...] = ("127.0.0.1",)):
        self.port, self.listen = free_port(), listen  # listen: more addresses for worker hosts (tests/faults/hosts.py)
        self.dir = tmp / f"redis-{self.port}"
        self.dir.mkdir(parents=True)
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def start(self) -> RedisServer:
        self.proc = subprocess.Popen(
            [shutil.which("redis-server") or "redis-server", "--port", str(self.port), "--bind", *self.listen,
             "--save", "", "--appendonly", "no", "--dir", str(self.dir),
             # no password on the private veth addresses of worker hosts (nothing is routed to them)
             "--protected-mode", "yes" if len(self.listen) == 1 else "no"],
            stdout=open(self.dir / "redis.log", "ab"), stderr=subprocess.STDOUT, start_new_session=True)
        import redis

        def up() -> bool:
            try:
                return redis.Redis.from_url(self.url, socket_timeout=0.5).ping()
            except Exception:
                return False
        _wait(up, 10, "redis start")
        return self

    def kill(self) -> None:
        """SIGKILL: everything in memory is lost (no persistence)."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
            self.proc.wait(timeout=10)


@cache
def _template() -> Path:
    """A cluster initdb'd and migrated once per test process, stopped cleanly: every :class:`PostgresServer`
    starts from a copy of its data directory (a tenth of a second) instead of its own initdb and migration
    (about 1.5 s, more on a loaded machine, for each of the fault tests' clusters)."""
    from app.runtime.migrate import upgrade

    root = Path(tempfile.mkdtemp(prefix="trajlab-pg-template-"))
    atexit.register(shutil.rmtree, root, ignore_errors=True)
    if os.geteuid() == 0:
        shutil.chown(root, "postgres", "postgres")
    subprocess.run(_as_postgres([str(PG_BIN / "initdb"), "-D", str(root / "data"), "-U", "postgres",
                                 "--auth=trust", "--no-sync", "-E", "UTF8"]),
                   check=True, capture_output=True, timeout=120)
    server = PostgresServer.__new__(PostgresServer)
    server.port, server.listen, server.dir, server.data = free_port(), ("127.0.0.1",), root, root / "data"
    server.start()
    try:
        upgrade(server.url)
    finally:
        server.stop()
    return root / "data"


class PostgresServer:
    """A PostgreSQL cluster of its own (a copy of the migrated template cluster) on a free port."""

    def __init__(self, listen: tuple[str, ...] = ("127.0.0.1",), root: Path | None = None):
        # root: an empty directory to hold the cluster (a small filesystem the test mounted, tests/faults/disk.py)
        self.port, self.listen = free_port(), listen
        self.dir = root or Path(tempfile.mkdtemp(prefix="trajlab-pg-"))
        self.data = self.dir / "data"
        if os.geteuid() == 0:
            shutil.chown(self.dir, "postgres", "postgres")
        # cp -a keeps the postgres user's ownership and the 0700 mode PostgreSQL insists on
        subprocess.run(["cp", "-a", str(_template()), str(self.data)], check=True, capture_output=True, timeout=120)
        if len(listen) > 1:  # worker hosts on private veth addresses (tests/faults/hosts.py), trusted as loopback is
            with open(self.data / "pg_hba.conf", "a") as hba:
                hba.writelines(f"host all all {addr.rsplit('.', 1)[0]}.0/24 trust\n" for addr in listen[1:])

    @property
    def url(self) -> str:
        return f"postgresql+psycopg://postgres@127.0.0.1:{self.port}/postgres"

    def start(self) -> PostgresServer:
        opts = f"-p {self.port} -k {self.dir} -c listen_addresses={','.join(self.listen)} -c fsync=off"
        subprocess.run(_as_postgres([str(PG_BIN / "pg_ctl"), "-D", str(self.data), "-o", opts, "-l",
                                     str(self.dir / "pg.log"), "-w", "-t", "60", "start"]),
                       check=True, capture_output=True, timeout=90)
        return self

    def stop(self) -> None:
        subprocess.run(_as_postgres([str(PG_BIN / "pg_ctl"), "-D", str(self.data), "-m", "fast", "-w", "stop"]),
                       capture_output=True, timeout=60)

    def destroy(self) -> None:
        self.stop()
        shutil.rmtree(self.dir, ignore_errors=True)
