"""Compiles that pay across two pools (issue 38 item 6): two real Celery worker processes, each a pool of one
solver process, the same problem structure submitted to both at once, on a PostgreSQL database and a Redis
database of their own, with ``TRAJLAB_JIT=background`` and one JIT cache directory (as ``trajlab serve``'s
two pools share ``TRAJLAB_DATA_DIR/jit``).

What is checked, from two independent witnesses:

* the cache directory's ``compiles.log`` (solvers.transcription.jit): every compile's start is followed by its
  own end before the next start (one compiler at a time), each structure is started once, and any process
  that wanted a structure while another compiled it recorded ``found`` instead of compiling it again;
* the process table, sampled every 5 ms while the jobs run: never more than one C compiler process (``cc``,
  ``cc1``, ...) working on this test's cache directory at once, and every one seen at nice 19 in an autogroup
  (its own session) at nice 19.

And the answers are the preset's (the brachistochrone's 1.8016 s) whichever derivatives each job used.
"""
from __future__ import annotations

import os
import threading
import time
import uuid
from pathlib import Path

import psycopg
import pytest
from sqlalchemy import text

from app.runtime.db import get_database
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings
from solvers.transcription import jit
from tests.integration.conftest import PG_ADMIN_URL, REDIS_URL, ROOT, Service, claim_redis_db

pytestmark = [pytest.mark.integration, pytest.mark.skipif(jit.compiler() is None, reason="no C compiler")]

COMPILERS = {"cc", "gcc", "clang", "cc1", "as", "collect2", "ld"}
BRACHISTOCHRONE_TF_S = 1.8016       # Dymos and GPOPS-II; the preset's grid gives 1.80160 s
TOLERANCE_S = 1e-4                  # the preset's own tolerance (its description)


def compiler_processes(marker: str) -> list[tuple[int, int, str, tuple[int, int | None]]]:
    """``(pid, parent pid, name, (nice, autogroup nice))`` of every compiler process whose command line names ``marker``
    (this test's cache directory: the driver and cc1 are given the generated source's path in it); the
    autogroup's nice is None on a kernel without autogroup scheduling."""
    out = []
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/stat") as f:
                stat = f.read()
            name = stat[stat.index("(") + 1:stat.rindex(")")]
            if name not in COMPILERS:
                continue
            with open(f"/proc/{entry.name}/cmdline", "rb") as f:
                cmdline = f.read().decode(errors="replace")
            fields = stat[stat.rindex(")") + 2:].split()             # from field 3 of /proc/PID/stat
            ppid, nice = int(fields[1]), int(fields[16])
            group: int | None = None
            if os.path.exists("/proc/self/autogroup"):
                with open(f"/proc/{entry.name}/autogroup") as f:      # "/autogroup-123 nice 19"
                    group = int(f.read().split()[-1])
        except (OSError, ValueError):
            continue                              # gone between the listing and the reads
        if marker in cmdline:
            out.append((int(entry.name), ppid, name, (nice, group)))
    return out


class Sampler(threading.Thread):
    def __init__(self, marker: str):
        super().__init__(daemon=True)
        self.marker, self.stop = marker, threading.Event()
        self.most_at_once, self.seen = 0, {}        # pid -> (name, (nice, autogroup nice))

    def run(self) -> None:
        while not self.stop.is_set():
            # by pid: a readdir of /proc while processes come and go may list one twice
            found = compiler_processes(self.marker)
            now = {pid: (ppid, name) for pid, ppid, name, _ in found}
            self.seen.update({pid: (name, nice) for pid, _, name, nice in found})
            # compiles in this one look at the process table (a pid seen earlier may be reused by now): drivers
            # not started by a driver (cc forks a copy of itself before it execs cc1), and cc1s
            drivers = sum(name in ("cc", "gcc", "clang") and ppid not in now for ppid, name in now.values())
            self.most_at_once = max(self.most_at_once, drivers, sum(name == "cc1" for _, name in now.values()))
            time.sleep(0.005)


@pytest.fixture
def two_pools(tmp_path):
    """Two worker processes (one solver process each) sharing one JIT cache, and the API under TestClient."""
    db_name = f"trajlab_jit_{uuid.uuid4().hex[:10]}"
    with psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5) as admin:
        admin.execute(f'CREATE DATABASE "{db_name}"')
    base = PG_ADMIN_URL.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1)
    db_url = f"{base}/{db_name}"
    upgrade(db_url)
    r, redis_url = claim_redis_db(REDIS_URL)
    cache = tmp_path / f"jit-{uuid.uuid4().hex[:8]}"
    cache.mkdir()
    overrides = {"TRAJLAB_DATABASE_URL": db_url, "TRAJLAB_BROKER_URL": redis_url,
                 "TRAJLAB_HEARTBEAT_INTERVAL_S": "0.5", "TRAJLAB_STALE_AFTER_S": "30"}
    env = {**os.environ, **overrides, "PYTHONPATH": str(ROOT), "TRAJLAB_JIT": "background",
           "TRAJLAB_JIT_CACHE": str(cache)}
    settings = Settings(**{k.removeprefix("TRAJLAB_").lower(): v for k, v in overrides.items()})
    svc = Service(settings, env, tmp_path)
    svc.start_worker(concurrency=1)
    svc.start_second_worker()
    svc.cache = cache
    try:
        yield svc
    finally:
        svc.stop_second_worker()
        svc.stop_worker()
        svc.client.close()
        svc.client.app.state.db.dispose()
        r.flushdb()
        get_database(db_url).dispose()
        with psycopg.connect(PG_ADMIN_URL, autocommit=True, connect_timeout=5) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{db_name}" WITH (FORCE)')


def wait_for_workers(svc: Service, logs: list[Path], timeout: float = 90) -> None:
    deadline = time.monotonic() + timeout
    while not all(p.exists() and b"ready." in p.read_bytes() for p in logs):
        assert time.monotonic() < deadline, f"workers not ready after {timeout} s: {logs}"
        time.sleep(0.2)


def test_two_pools_compile_one_at_a_time_and_each_structure_once(two_pools):
    svc = two_pools
    wait_for_workers(svc, [svc.log_dir / "worker-1.log", svc.log_dir / "worker-second.log"])
    sampler = Sampler(str(svc.cache))
    sampler.start()
    # Four jobs of one preset at once: each pool takes one at the same moment, so both want the same
    # structures while neither is compiled yet (a preset is worth compiling on first sight).
    ids = [svc.submit("ocp", preset="brachistochrone").json()["id"] for _ in range(4)]
    jobs = [svc.wait(i, timeout=300) for i in ids]
    time.sleep(2.0)                     # compiles that outlive their job finish (the libraries below)
    deadline = time.monotonic() + 120
    while (svc.cache / jit.RECORDS).exists() and any(
            e == "start" for e in _unfinished(svc.cache)) and time.monotonic() < deadline:
        time.sleep(0.2)
    sampler.stop.set()
    sampler.join()

    assert [j["status"] for j in jobs] == ["succeeded"] * 4, [j["message"] for j in jobs]
    for i in ids:
        assert abs(svc.result(i)["objective"]["value"] - BRACHISTOCHRONE_TF_S) < TOLERANCE_S     # minimum tf
    with svc.client.app.state.db.engine.connect() as conn:
        workers = {row[0] for row in conn.execute(text("SELECT worker FROM jobs"))}
    assert len(workers) == 2, f"both pools ran a job: {workers}"

    records = [line.split() for line in (svc.cache / jit.RECORDS).read_text().splitlines()]
    events = [(int(pid), event, key) for _, pid, event, key in records]
    compiles = [e for e in events if e[1] != "found"]
    assert compiles, "the preset's structures were compiled (a preset is worth it on first sight)"
    assert [e[1] for e in compiles] == ["start", "end"] * (len(compiles) // 2)      # never two at once
    assert all(a[0] == b[0] and a[2] == b[2] for a, b in zip(compiles[::2], compiles[1::2]))
    started = [e[2] for e in compiles[::2]]
    assert len(started) == len(set(started)), f"a structure compiled twice: {started}"
    assert all((svc.cache / f"nlp_{k}.so").exists() for k in started)
    compiled_by = {key: pid for pid, _, key in compiles[::2]}
    assert all(compiled_by.get(key) not in (None, pid) for pid, event, key in events if event == "found")
    # the process table agrees: at most one compiler at once, each at the lowest priority
    assert sampler.most_at_once <= 1, sampler.seen
    assert all(nice == 19 and group in (None, 19) for _, (nice, group) in sampler.seen.values()), sampler.seen
    print(f"\ncompiles: {len(started)} structures, {sum(e[1] == 'found' for e in events)} found done by a waiter; "
          f"compiler processes seen: {sorted(n for n, _ in sampler.seen.values())}")


def _unfinished(cache: Path) -> list[str]:
    """Events of compiles started and not yet ended."""
    open_: dict[str, str] = {}
    for line in (cache / jit.RECORDS).read_text().splitlines():
        _, _, event, key = line.split()
        if event == "start":
            open_[key] = event
        elif event == "end":
            open_.pop(key, None)
    return list(open_.values())
