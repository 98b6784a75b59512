"""No database connection crosses a fork (issue 36 item 7).

Celery's main process opens the database (``JobTask.on_failure`` stores a job the hard time limit killed;
the recovery thread) and forks pool children afterwards.  Here the same happens with ``os.fork``: the parent
opens the cached Database as ``on_failure`` does (real PostgreSQL), the child queries, and the child's
backend is another one than the parent's (the same backend pid would mean both talk over one socket); the
parent's connection still answers afterwards, from the same backend (the child did not close it).  On
SQLite, a fork while another thread of the parent holds the process's write lock leaves the child able to
write (an inherited held lock would never be released).
"""
from __future__ import annotations

import os
import threading
import time

import pytest
from sqlalchemy import text

from app.runtime.db import Database, get_database
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings

pytestmark = pytest.mark.integration


def _in_child(work) -> bytes:
    """``work()``'s bytes from a forked child (its exit status 0 only if it returned), waited for up to 120 s."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:   # the child: no pytest machinery past this point
        code = 1
        try:
            os.write(w, work())
            code = 0
        finally:
            os._exit(code)
    os.close(w)
    deadline = time.monotonic() + 120
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            raise AssertionError("the forked child did not finish within 120 s (a lock inherited held?)")
        time.sleep(0.05)
    out = os.read(r, 1000)
    os.close(r)
    assert os.waitstatus_to_exitcode(status) == 0, out
    return out


def _backend(db: Database) -> int:
    with db.read_connection() as conn:
        return conn.execute(text("SELECT pg_backend_pid()")).scalar_one()


def test_a_forked_child_opens_its_own_connection_and_leaves_the_parents(pg_url):
    upgrade(pg_url)
    settings = Settings(database_url=pg_url)
    # A Database of its own, opened as JobTask.on_failure opens one in Celery's main process: the cached one
    # may hold several idle connections left by earlier tests, and its FIFO pool would hand out another
    # backend on the next checkout than the one measured (seen in a whole-suite run).
    db = Database(pg_url, settings)
    parent = _backend(db)                  # a connection now idle in the parent's pool
    child = int(_in_child(lambda: str(_backend(db)).encode()))   # the same object, inherited by the child
    assert child != parent
    assert _backend(db) == parent          # the parent's connection is still there, and still works
    db.dispose()


def test_a_fork_while_the_sqlite_write_lock_is_held_leaves_the_child_able_to_write(tmp_path):
    url = f"sqlite:///{tmp_path / 'fork.db'}"
    upgrade(url)
    db = get_database(url)
    held, release = threading.Event(), threading.Event()

    def writer():
        with db.write():
            held.set()
            release.wait(120)

    thread = threading.Thread(target=writer)
    thread.start()
    assert held.wait(60)
    try:
        def child_writes() -> bytes:
            # the child takes the process's write lock (which must not be the inherited, held one), then its
            # BEGIN IMMEDIATE waits (busy timeout) for the file lock the parent's transaction holds until
            # the timer below ends it
            with db.write() as s:
                s.execute(text("UPDATE leases SET holder = holder WHERE 1 = 0"))
            return b"wrote"

        # the file lock is the parent's until it commits: release it shortly after the fork, from the parent
        timer = threading.Timer(0.5, release.set)
        timer.start()
        assert _in_child(child_writes) == b"wrote"
    finally:
        release.set()
        thread.join(timeout=60)
