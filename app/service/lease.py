"""A lease in the database: at most one process at a time holds a named duty, another takes over when
the holder stops renewing it.

The recovery duties (reaper, re-publisher, studies, retention: ``app.service.recovery``) run in every
worker's main process, in ``trajlab serve`` and in any ``trajlab recover``; the ``leases`` row named
:data:`RECOVERY` says which of them does the work.  A holder renews the lease (``expires_at`` = now +
its length) a few times per length; a candidate takes it only when it has expired.  Both are one
conditional ``UPDATE`` (a compare-and-set), so on PostgreSQL the row lock serializes two candidates
and the second sees the first's new expiry (READ COMMITTED re-reads the row it waited for); on SQLite
the write transactions are serialized anyway.  ``renewed_at`` is the recovery heartbeat ``/readyz``
reads.

Why a row and not a PostgreSQL advisory lock: an advisory lock lives as long as its session, so a
holder cut from the database keeps it until TCP notices (minutes), and SQLite has none; a row with an
expiry works on both and expires on the clock.  The clock is the database's on PostgreSQL
(``clock_timestamp()``): holders on different hosts compare expiries against one clock, never their
own.  SQLite is one machine: its clock is the host's.
"""
from __future__ import annotations

import os
import socket
import uuid
from dataclasses import dataclass
from typing import Any, cast
from datetime import datetime, timedelta, timezone

from sqlalchemy import CursorResult, func, insert, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.runtime.db import Database
from app.runtime.models import Lease, utcnow

RECOVERY = "recovery"


def holder_id() -> str:
    """A name for this process as a holder: host, pid and a random part (a pid is reused)."""
    return f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"


def _now(session: Session) -> datetime:
    if session.get_bind().dialect.name == "postgresql":
        return session.execute(select(func.clock_timestamp())).scalar_one()
    return utcnow()


def _rowcount(result: Any) -> int:
    # an UPDATE's result is a CursorResult; Session.execute is typed with the general Result
    return cast(CursorResult, result).rowcount


def _aware(dt: datetime) -> datetime:
    # SQLite gives naive datetimes back (stored as UTC)
    return dt if dt.tzinfo is not None else dt.replace(tzinfo=timezone.utc)


def acquire(db: Database, name: str, holder: str, *, length_s: float) -> bool:
    """Take or renew the lease ``name`` for ``length_s`` seconds; True if ``holder`` holds it now."""
    with db.write() as s:
        now = _now(s)
        expires = now + timedelta(seconds=length_s)
        held = _rowcount(s.execute(update(Lease).where(Lease.name == name, Lease.holder == holder)
                                   .values(expires_at=expires, renewed_at=now)))
        if held:
            return True
        taken = _rowcount(s.execute(update(Lease).where(Lease.name == name, Lease.expires_at < now)
                                    .values(holder=holder, acquired_at=now, expires_at=expires, renewed_at=now)))
        if taken:
            return True
        if s.get(Lease, name) is not None:
            return False
    try:  # no row yet (migration 0007 makes the recovery row; any other name starts here)
        with db.write() as s:
            now = _now(s)
            s.execute(insert(Lease).values(name=name, holder=holder, acquired_at=now, renewed_at=now,
                                           expires_at=now + timedelta(seconds=length_s)))
        return True
    except IntegrityError:  # another candidate inserted it first
        return False


def release(db: Database, name: str, holder: str) -> None:
    """Give the lease up now (a clean stop), so the next candidate need not wait for it to expire."""
    with db.write() as s:
        s.execute(update(Lease).where(Lease.name == name, Lease.holder == holder)
                  .values(expires_at=_now(s)))


@dataclass(frozen=True)
class LeaseState:
    holder: str | None
    renewed_age_s: float | None  # seconds since the last renewal; None: never held
    expired: bool


def state(db: Database, name: str) -> LeaseState:
    """Who holds ``name`` and how long ago it was renewed, by the database's clock."""
    with db.read() as s:
        now = _now(s)
        row = s.get(Lease, name)
        if row is None or row.renewed_at is None:
            return LeaseState(None, None, True)
        return LeaseState(row.holder, (now - _aware(row.renewed_at)).total_seconds(),
                          _aware(row.expires_at) <= now)
