"""Engine and session handling for SQLite (embedded) and PostgreSQL (production).

SQLite under concurrent writers (API threads, worker processes, the reaper) needs
three things, measured here: WAL so readers never block the writer; a busy
timeout so a writer waits instead of failing with "database is locked"; and
short write transactions, serialized inside each process and opened with
``BEGIN IMMEDIATE`` so that a read-then-write transaction can never hit the
un-retryable lock-upgrade deadlock.  PostgreSQL needs none of it.

PostgreSQL's pool holds as many connections as requests run at once in one API
process (``POOL_SIZE``, the size of its thread pool): with 5 kept and the rest
opened and closed per request, every overflow request paid a new connection (a
backend fork).  A connection that sat
idle longer than ``PING_IDLE_S`` is pinged before use (a database restart is then
invisible to the next request); one in constant use is not, which saves a round
trip per request under load (``pool_pre_ping`` pinged every checkout).  If the
database restarts under load, the request that meets a dead connection is a 503
and SQLAlchemy discards the pool's older connections at once.

Reads on PostgreSQL run in autocommit: at READ COMMITTED (PostgreSQL's default,
ours) every statement takes its own snapshot inside a transaction too, so a
read-only transaction bought nothing but two more round trips per request (psycopg
sends ``BEGIN`` before the first statement and the pool a ``ROLLBACK`` at check-in:
a third of a ``GET /v1/jobs/{id}``'s time, measured with py-spy).  A write that is
one statement (:meth:`Database.autocommit`) is atomic on its own, for the same reason.

Every PostgreSQL connection of the service is bounded in time (:func:`pg_connect_args`, the settings
``db_*``): a connect over a dead link fails after ``connect_timeout``; a statement whose packets go
unacknowledged fails after ``tcp_user_timeout``; an idle or waiting connection whose peer vanished is
found by TCP keepalives; a query the server runs too long is cancelled by ``statement_timeout``.
Without them a call over a cut link waited for the kernel to give up (``tcp_retries2``: about 15
minutes) and the worker's bounded store retry never ran.  Migrations (``migrations/env.py``) connect
without the statement timeout.

No connection crosses a fork (issue 36).  Celery's main process opens the database (``JobTask.on_failure``,
the recovery thread) and forks pool children later; a child that used an inherited pooled connection would
share its socket with the parent, and the two interleave protocol messages on one backend.  Every
:class:`Database` is therefore forgotten in a forked child: its pool dropped without closing the parent's
connections (SQLAlchemy's ``dispose(close=False)``, as its documentation prescribes for forks), and its
SQLite write lock made anew (one held by another thread of the parent at the fork would never be released).
"""
from __future__ import annotations

import os
import threading
import time
import weakref
from contextlib import contextmanager
from typing import TYPE_CHECKING, Iterator

from sqlalchemy import Connection, Engine, create_engine, event
from sqlalchemy.exc import DisconnectionError
from sqlalchemy.orm import Session, sessionmaker

if TYPE_CHECKING:
    from app.runtime.settings import Settings

SQLITE_BUSY_TIMEOUT_MS = 30_000
# Connections kept, one per API thread (app.api.main); MAX_OVERFLOW more for other threads/bursts.  8 per process:
# with 2 API processes (the default), 16 threads each queued behind one another for the GIL and POST at
# 100 connections had a p99 of 675 ms; 8 each (16 in all, as one process had) 315 ms, at 1.5x the
# throughput (benchmarks/api_load.py, same machine, minutes apart).
POOL_SIZE = 8
MAX_OVERFLOW = 8
PING_IDLE_S = 5.0


def pg_connect_args(settings: "Settings", *, statement_timeout: bool = True) -> dict:
    """psycopg (libpq) connection parameters that bound every call in time (module docstring)."""
    args: dict[str, int | str] = {
        "connect_timeout": int(settings.db_connect_timeout_s),
        "keepalives": 1,
        "keepalives_idle": int(settings.db_keepalives_idle_s),
        "keepalives_interval": int(settings.db_keepalives_interval_s),
        "keepalives_count": int(settings.db_keepalives_count),
        "tcp_user_timeout": int(settings.db_tcp_user_timeout_s * 1000),
    }
    if statement_timeout:
        args["options"] = f"-c statement_timeout={int(settings.db_statement_timeout_s * 1000)}"
    return args


def make_engine(url: str, settings: "Settings | None" = None, *, statement_timeout: bool = True) -> Engine:
    """The engine for ``url``; on PostgreSQL with the network timeouts of ``settings`` (default: the
    environment's)."""
    if url.startswith("sqlite"):
        engine = create_engine(url, connect_args={"check_same_thread": False, "timeout": SQLITE_BUSY_TIMEOUT_MS / 1000})

        @event.listens_for(engine, "connect")
        def _on_connect(dbapi_conn, _record):
            # Take transaction control from pysqlite so "begin" below decides the mode.
            dbapi_conn.isolation_level = None
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
            cur.execute("PRAGMA synchronous=NORMAL")
            cur.execute("PRAGMA foreign_keys=ON")
            cur.close()

        @event.listens_for(engine, "begin")
        def _on_begin(conn):
            immediate = conn.get_execution_options().get("sqlite_immediate", False)
            conn.exec_driver_sql("BEGIN IMMEDIATE" if immediate else "BEGIN")

        return engine
    if settings is None:
        from app.runtime.settings import get_settings

        settings = get_settings()
    engine = create_engine(url, pool_size=POOL_SIZE, max_overflow=MAX_OVERFLOW, pool_timeout=settings.db_pool_timeout_s,
                           connect_args=pg_connect_args(settings, statement_timeout=statement_timeout))

    @event.listens_for(engine, "connect")
    @event.listens_for(engine, "checkin")
    def _fresh(_dbapi_conn, record):
        if record is not None:
            record.info["checked_in"] = time.monotonic()

    @event.listens_for(engine, "checkout")
    def _on_checkout(dbapi_conn, record, _proxy):
        # SQLAlchemy's documented pessimistic disconnect handling, for idle connections only:
        # DisconnectionError makes the pool drop this connection and check out a fresh one.
        if time.monotonic() - record.info.get("checked_in", 0.0) > PING_IDLE_S:
            try:
                with dbapi_conn.cursor() as cur:
                    cur.execute("SELECT 1")
                dbapi_conn.rollback()  # hand it over idle, as the pool keeps it
            except Exception as exc:
                raise DisconnectionError(str(exc)) from exc

    return engine


class Database:
    """Session factory with a read path and a serialized write path."""

    def __init__(self, url: str, settings: "Settings | None" = None):
        self.url = url
        self.engine = make_engine(url, settings)
        self.is_sqlite = self.engine.dialect.name == "sqlite"
        # PostgreSQL reads in autocommit (module docstring); the isolation level is per checkout, the
        # pool is shared, and SQLAlchemy restores it when the connection goes back
        self._read_engine = self.engine if self.is_sqlite else self.engine.execution_options(
            isolation_level="AUTOCOMMIT")
        self._read = sessionmaker(self._read_engine, expire_on_commit=False)
        self._write_engine = self.engine.execution_options(sqlite_immediate=True) if self.is_sqlite else self.engine
        self._write = sessionmaker(self._write_engine, expire_on_commit=False)
        self._write_lock = threading.Lock() if self.is_sqlite else None
        _EVERY_DATABASE.add(self)

    def _after_fork_in_child(self) -> None:
        self.engine.dispose(close=False)   # the parent's connections stay open, for the parent
        if self._write_lock is not None:
            self._write_lock = threading.Lock()

    @contextmanager
    def read(self) -> Iterator[Session]:
        with self._read() as session:
            yield session

    @contextmanager
    def read_connection(self) -> Iterator[Connection]:
        """A Core connection for reads (no ORM session: the hot routes' single statements)."""
        with self._read_engine.connect() as conn:
            yield conn

    @contextmanager
    def _serialized(self) -> Iterator[None]:
        """Holds the process's SQLite write lock (nothing on PostgreSQL): module docstring."""
        if self._write_lock is None:
            yield
            return
        with self._write_lock:
            yield

    @contextmanager
    def write_connection(self) -> Iterator[Connection]:
        """:meth:`write` as a Core connection in a transaction: committed on success, rolled back on error."""
        with self._serialized(), self._write_engine.begin() as conn:
            yield conn

    @contextmanager
    def autocommit(self) -> Iterator[Connection]:
        """A Core connection for a write of one statement, which is atomic by itself: on PostgreSQL no
        BEGIN/COMMIT round trips; on SQLite the same serialized ``BEGIN IMMEDIATE`` transaction as
        :meth:`write_connection` (pysqlite's own transaction control is off, app.runtime.db.make_engine)."""
        if self.is_sqlite:
            with self.write_connection() as conn:
                yield conn
            return
        with self._read_engine.connect() as conn:
            yield conn

    @contextmanager
    def write(self) -> Iterator[Session]:
        """A short write transaction: committed on success, rolled back on error."""
        with self._serialized(), self._write() as session, session.begin():
            yield session

    def dispose(self) -> None:
        self.engine.dispose()


# Every Database of this process, held weakly: a forked child forgets their pooled connections (module docstring)
_EVERY_DATABASE: weakref.WeakSet[Database] = weakref.WeakSet()


def _forget_connections_in_child() -> None:
    for db in list(_EVERY_DATABASE):
        db._after_fork_in_child()


os.register_at_fork(after_in_child=_forget_connections_in_child)

_DATABASES: dict[str, Database] = {}
_DB_LOCK = threading.Lock()


def get_database(url: str, settings: "Settings | None" = None) -> Database:
    """One :class:`Database` per URL per process (so the write lock is process-wide); the first caller's
    ``settings`` (default: the environment's) give its timeouts."""
    with _DB_LOCK:
        db = _DATABASES.get(url)
        if db is None:
            db = _DATABASES[url] = Database(url, settings)
        return db
