"""What a job keeps in the database, and how much: results written compressed, read in either form,
and the bytes each owner stores (``GET /v1/usage``, the storage quota).

``jobs.stored_bytes`` is the job's params' JSON plus its result as stored (compressed, by
:mod:`app.runtime.result_codec`).  It is set when the job is created and again when its result is
stored, in the same transaction, and goes with the row when the job is deleted; so an owner's usage
is one ``SUM`` over a column of ``jobs`` and never reads a result.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

from sqlalchemy import Connection, func, null, select
from sqlalchemy.orm import Session

from app.runtime import result_codec
from app.runtime.db import Database
from app.runtime.models import Job, StoredResult, utcnow
from app.runtime.settings import Settings

MB = 1 << 20  # TRAJLAB_MAX_STORED_MB_PER_OWNER counts MiB, as the README says


def params_bytes(params: dict) -> int:
    """The size of a job's params as JSON (what its row holds besides small columns)."""
    return len(json.dumps(params, separators=(",", ":"), ensure_ascii=False).encode())


@dataclass(frozen=True)
class Packed:
    """A result document encoded for storage (encode it before the write transaction: it is CPU)."""

    data: bytes
    encoding: str


def pack(result: dict) -> Packed:
    data, encoding = result_codec.encode(result)
    return Packed(data, encoding)


def put_result(session: Session, job: Job, packed: Packed) -> None:
    """Store ``packed`` as ``job``'s result (replacing any) and count it in ``job.stored_bytes``,
    in the caller's transaction."""
    row = session.get(StoredResult, job.id)
    if row is None:
        session.add(StoredResult(job_id=job.id, packed=packed.data, encoding=packed.encoding, created_at=utcnow()))
    else:  # SQL NULL, not the JSON text 'null' that None would write
        row.data, row.packed, row.encoding = null(), packed.data, packed.encoding
    job.stored_bytes = params_bytes(job.params) + len(packed.data)


def read_result(row: StoredResult | None) -> dict | None:
    """The document of a stored result row, compressed or written before revision 0006."""
    return None if row is None else result_codec.decode(row.packed, row.encoding, row.data)


def owner_stored_bytes(conn: Session | Connection, owner: str | None) -> int:
    """Bytes the owner's jobs keep (None: every job's, for the auth-off local user and admins)."""
    q = select(func.coalesce(func.sum(Job.stored_bytes), 0))
    if owner is not None:
        q = q.where(Job.owner == owner)
    return int(conn.execute(q).scalar() or 0)


def max_stored_bytes(settings: Settings) -> int | None:
    mb = settings.max_stored_mb_per_owner
    return None if mb is None else int(mb * MB)


def usage(db: Database, settings: Settings, *, owner: str | None) -> dict:
    """An owner's jobs by status and stored bytes, with the storage cap (``GET /v1/usage``)."""
    q = select(Job.status, func.count(), func.coalesce(func.sum(Job.stored_bytes), 0)).group_by(Job.status)
    if owner is not None:
        q = q.where(Job.owner == owner)
    with db.read_connection() as conn:
        rows = conn.execute(q).all()
    by_status = {status: int(n) for status, n, _ in rows}
    return {"owner": owner, "jobs": sum(by_status.values()), "jobs_by_status": by_status,
            "stored_bytes": sum(int(b) for *_, b in rows), "max_stored_bytes": max_stored_bytes(settings),
            "retention_days": settings.retention_days}
