"""Job persistence: every state change of a job is one short write transaction here.

The API and the worker share these functions, so the rules of the life cycle
live in one place:

* a job row is committed before its message is published (``create_job``);
* ``attempts`` is a delivery token: a message carries the attempt it was
  published for, and only the delivery holding the current token may claim,
  report on or finish the job, so a stale or duplicated message is harmless;
* a job whose worker died is re-queued by bumping the token (``reap_stale`` and
  ``claim``), at most ``max_attempts`` times, then fails with ``worker_lost``.
"""
from __future__ import annotations

import functools
import typing
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from typing import TYPE_CHECKING, Callable

from sqlalchemy import Connection, Row, Text, bindparam, cast, func, insert, or_, select, update
from sqlalchemy.orm import Session

from app.kinds.failures import ERROR_CODES
from app.service import storage
from app.service.job_document import listed_job_json
from app.service.broker import QUEUE_JOBS
from app.runtime.db import Database
from app.runtime.models import FINAL_STATUSES, Job, StoredResult, new_id, utcnow

JOBS = Job.metadata.tables[Job.__tablename__]  # Job.__table__, typed as the Table it is
# A job's columns as a read-only row: the same attribute names as a Job (job.status, job.owner, ...), read by
# Core without the ORM's identity map and unit of work (the hot routes: half a GET's CPU was Session.get).
# To the type checker it is the Job it reads like.
if TYPE_CHECKING:
    JobRow = Job
else:
    JobRow = Row


def _aware(dt: datetime) -> datetime:
    return dt.replace(tzinfo=timezone.utc) if dt.tzinfo is None else dt  # SQLite returns naive UTC


def _job_filters(*, kind, status, owner) -> list:
    """Conditions on the given filters (values or bound parameters; None or empty: no condition)."""
    conds = []
    if owner is not None:
        conds.append(Job.owner == owner)
    if kind is not None:
        conds.append(Job.kind == kind)
    if status is not None:
        conds.append(Job.status == status)
    return conds


class IdempotencyConflict(Exception):
    """The Idempotency-Key was used before for a different request."""


_INSERT_JOB = insert(JOBS)
_JOB_BY_IDEMPOTENCY_KEY = select(JOBS).where(JOBS.c.idempotency_key == bindparam("key"))


def queued_job_values(*, kind: str, params: dict, label: str | None, preset: str | None, owner: str | None,
                      queue: str, **extra) -> dict:
    """The columns of a new queued job (attempt 1): a submitted job's row (:func:`create_job`) and a study
    point's (``app.service.studies``); ``extra`` sets the others (idempotency key, study and point)."""
    now = utcnow()
    # Marked as handed to the broker in the same INSERT (no second write per submission): if the
    # publish then fails, mark_unpublished clears it; if the process dies in between, the
    # re-publisher finds the job missing from the broker and sends it (app/service/recovery.py).
    return dict(id=new_id(), kind=kind, params=params, label=label, preset=preset, status="queued",
                progress=0.0, message="queued", attempts=1, cancel_requested=False, created_at=now,
                owner=owner, queue=queue, published_at=now, stored_bytes=storage.params_bytes(params), **extra)


def create_job(db: Database, *, kind: str, params: dict, label: str | None, preset: str | None,
               idempotency_key: str | None = None, request_hash: str | None = None,
               owner: str | None = None, queue: str = QUEUE_JOBS,
               admit: Callable[[Connection], None] | None = None,
               request_id: str | None = None) -> tuple[Job | JobRow, bool]:
    """Insert a queued job (attempt 1) of ``owner`` for ``queue``. Returns ``(job, created)``; an
    identical request of the same owner with a known ``idempotency_key`` returns the existing job
    (its row).

    ``admit(connection)`` runs in the same transaction just before a new job is inserted (never for a
    repeated request) and refuses it by raising (the quota check): the idempotency lookup, the quota
    and the insert are one transaction on one connection, not three.  Without either, the insert is
    one statement, atomic by itself (:meth:`Database.autocommit`: one round trip on PostgreSQL)."""
    values = queued_job_values(kind=kind, params=params, label=label, preset=preset, owner=owner, queue=queue,
                               idempotency_key=idempotency_key, request_hash=request_hash, request_id=request_id)
    # A Core INSERT: the ORM's unit of work was a fifth of a submission's CPU for one row.
    if idempotency_key is None and admit is None:
        with db.autocommit() as conn:
            conn.execute(_INSERT_JOB, values)
        return Job(**values), True
    with db.write_connection() as conn:
        if idempotency_key is not None:
            existing = conn.execute(_JOB_BY_IDEMPOTENCY_KEY, {"key": idempotency_key}).first()
            if existing is not None:
                # Another owner's key is a conflict, never their job.
                if existing.request_hash != request_hash or existing.owner != owner:
                    raise IdempotencyConflict(idempotency_key)
                return typing.cast(JobRow, existing), False
        if admit is not None:
            admit(conn)
        conn.execute(_INSERT_JOB, values)
    return Job(**values), True


def active_jobs(session: Session | Connection, owner: str | None) -> list:
    """The owner's queued and running jobs (what quotas count: rows of ``status``, ``kind``, ``params``),
    read in the caller's transaction; bounded by the per-owner limits."""
    return list(session.execute(select(Job.status, Job.kind, Job.params).where(
        Job.owner == owner, Job.status.in_(("queued", "running")))))


NEWEST_FIRST = (Job.created_at.desc(), Job.id.desc())


def list_jobs(db: Database, *, kind: str | None, status: str | None, limit: int, offset: int,
              owner: str | None = None) -> tuple[list[Job], int]:
    """Newest first; ``owner`` restricts to that owner's jobs (None: every job)."""
    conds = _job_filters(kind=kind or None, status=status or None, owner=owner)
    with db.read() as s:
        items = list(s.scalars(select(Job).where(*conds).order_by(*NEWEST_FIRST).limit(limit).offset(offset)))
        total = int(s.scalar(select(func.count()).select_from(Job).where(*conds)) or 0)
    return items, total


@functools.cache
def _list_statements(*, owner: bool, kind: bool, status: bool):
    """The listing's two statements for one combination of filters, built once with bound parameters:
    building them per request (and SQLAlchemy adapting its cached compilation to each new object) was
    a fifth of a listing's CPU."""
    conds = _job_filters(owner=bindparam("owner") if owner else None, kind=bindparam("kind") if kind else None,
                         status=bindparam("status") if status else None)
    count = select(func.count()).select_from(Job).where(*conds)
    q = (select(Job.id, Job.kind, Job.label, Job.preset, Job.status, Job.progress, Job.message, Job.stage,
                Job.stage_round, Job.created_at,
                Job.started_at, Job.finished_at, cast(Job.params, Text).label("params_json"), Job.error,
                Job.attempts, count.scalar_subquery().label("total"))
         .where(*conds).order_by(*NEWEST_FIRST).limit(bindparam("limit")).offset(bindparam("offset")))
    return q, count


def list_jobs_json(db: Database, *, kind: str | None, status: str | None, limit: int, offset: int,
                   owner: str | None = None) -> bytes:
    """:func:`list_jobs` as the API's ``JobList`` JSON, in one round trip: the total rides along as an
    uncorrelated scalar subquery (computed once), and the rows are plain columns, not ORM objects."""
    q, count = _list_statements(owner=owner is not None, kind=bool(kind), status=bool(status))
    args = {"owner": owner, "kind": kind, "status": status, "limit": limit, "offset": offset}
    with db.read_connection() as conn:
        rows = conn.execute(q, args).all()
        total = rows[0].total if rows else int(conn.scalar(count, args) or 0)  # past the end: ask for it alone
    return f'{{"items":[{",".join(listed_job_json(r) for r in rows)}],"total":{int(total)}}}'.encode()


def get_job(db: Database, job_id: str) -> Job | None:
    with db.read() as s:
        return s.get(Job, job_id)


_JOB_BY_ID = select(JOBS).where(JOBS.c.id == bindparam("job_id"))


def get_job_row(db: Database, job_id: str) -> JobRow | None:
    """The job's columns (:data:`JobRow`), or None: :func:`get_job` for readers, in one statement."""
    with db.read_connection() as conn:
        return typing.cast("JobRow | None", conn.execute(_JOB_BY_ID, {"job_id": job_id}).first())


def get_result(db: Database, job_id: str) -> dict | None:
    with db.read() as s:
        return storage.read_result(s.get(StoredResult, job_id))


def request_cancel(db: Database, job_id: str) -> Job | None:
    """A queued job is cancelled at once (it will never start); a running one gets
    the flag its solver polls; a finished one is left as it is."""
    with db.write() as s:
        job = s.get(Job, job_id)
        if job is None:
            return None
        if job.status == "queued":
            job.status = "cancelled"
            job.cancel_requested = True
            job.finished_at = utcnow()
            job.message = "cancelled before it started"
            job.error = {"code": "cancelled", "message": "cancelled by request before it started"}
        elif job.status == "running":
            job.cancel_requested = True
            job.message = "cancellation requested"
    return job


def mark_unpublished(db: Database, job_id: str) -> None:
    """The broker could not take the job's message: it stays queued, and the re-publisher sends it
    as soon as the broker is back (never stored as failed: the job was accepted)."""
    mark_unpublished_many(db, [job_id])


def mark_unpublished_many(db: Database, job_ids: list[str]) -> None:
    """:func:`mark_unpublished` for many jobs in one statement (the API's publisher, app.service.publisher)."""
    if not job_ids:
        return
    with db.write() as s:
        s.execute(update(Job).where(Job.id.in_(job_ids), Job.status == "queued").values(
            published_at=None, message="queued; waiting for the broker (it will be published when it is back)"))


def publish_candidates(db: Database, *, older_than_s: float) -> list[Job]:
    """Queued jobs never published, or published more than ``older_than_s`` ago and still not claimed."""
    cutoff = utcnow() - timedelta(seconds=older_than_s)
    with db.read() as s:
        return list(s.scalars(select(Job).where(
            Job.status == "queued", or_(Job.published_at.is_(None), Job.published_at < cutoff))
            .order_by(Job.created_at)))


def mark_published(db: Database, job_ids: list[str]) -> None:
    if not job_ids:
        return
    with db.write() as s:
        s.execute(update(Job).where(Job.id.in_(job_ids), Job.status == "queued").values(published_at=utcnow()))


@dataclass
class Claim:
    job_id: str
    kind: str
    params: dict
    attempt: int
    # the X-Request-ID of the submission (app.runtime.logs), for the worker's log lines
    request_id: str | None = None
    # submission to this first start (None when the job had started before: a re-run)
    queue_wait_s: float | None = None
    owner: str | None = None
    # a preset's or a study's point: its problem structure is likely to come back, so compiling its
    # derivatives pays (solvers.transcription.jit.expected_again)
    recurring: bool = False


def claim(db: Database, job_id: str, attempt: int, *, worker: str, max_attempts: int,
          stale_after_s: float) -> Claim | None:
    """Move a job to ``running`` for the delivery holding token ``attempt``.

    A second delivery of a job that is ``running`` with a fresh heartbeat is a
    duplicate message (re-published, or delivered twice by the broker): it is
    dropped and never takes the job over.  Only when the heartbeat is stale (its
    worker died; acks_late + reject_on_worker_lost gave the message back) does
    a delivery take the job over with a new token, up to ``max_attempts``.
    Returns None when this delivery must not run the job.
    """
    with db.write() as s:
        job = s.get(Job, job_id)
        if job is None or job.status in FINAL_STATUSES or job.attempts != attempt:
            return None
        if job.cancel_requested:
            _finish(job, "cancelled", error={"code": "cancelled", "message": "cancelled by request"},
                    message="cancelled")
            return None
        now = utcnow()
        if job.status == "running":
            beat = job.heartbeat_at
            if beat is not None and beat.tzinfo is None:  # SQLite returns naive UTC
                beat = beat.replace(tzinfo=timezone.utc)
            if beat is not None and (now - beat).total_seconds() < stale_after_s:
                return None  # alive elsewhere: a duplicate
            if job.attempts >= max_attempts:
                _fail_worker_lost(job, max_attempts)
                return None
            job.attempts += 1
        job.status = "running"
        # delivered, so published: a message the broker took although its sender saw a timeout (a reply lost
        # in a silent cut) left the row unpublished, and nothing else would ever set it
        job.published_at = job.published_at or now
        queue_wait_s = None if job.started_at is not None else (now - _aware(job.created_at)).total_seconds()
        job.started_at = job.started_at or now
        job.heartbeat_at = now
        job.worker = worker
        job.message = f"started on {worker} (attempt {job.attempts})"
        job.stage, job.stage_round = None, None      # an attempt announces its own stages
        return Claim(job.id, job.kind, dict(job.params), job.attempts, request_id=job.request_id,
                     queue_wait_s=queue_wait_s, owner=job.owner,
                     recurring=job.preset is not None or job.study_id is not None)


def heartbeat(db: Database, job_id: str, attempt: int, *, progress: float | None, message: str | None,
              stage: str | None = None, stage_round: int | None = None) -> bool | None:
    """Write heartbeat (and progress, and the stage announced with its round) for the current token;
    returns the cancel flag, or None if this delivery no longer owns the job."""
    with db.write() as s:
        job = s.get(Job, job_id)
        if job is None or job.status != "running" or job.attempts != attempt:
            return None
        job.heartbeat_at = utcnow()
        if progress is not None and progress > job.progress:  # progress only grows
            job.progress = min(float(progress), 1.0)
        if message is not None:   # the stage goes with its message (None: a message of no declared stage)
            job.message = message[:2000]
            job.stage, job.stage_round = (None if stage is None else stage[:200]), stage_round
        return bool(job.cancel_requested)


def _known_code(error: dict | None) -> dict | None:
    """``error`` with a code of the one declaration (app.kinds.failures.ERROR_CODES); a code nobody declared
    is a bug, stored as ``internal`` naming it, so the job document always fits the OpenAPI enum."""
    if error is None or error.get("code") in ERROR_CODES:
        return error
    details = {**(error.get("details") or {}), "undeclared_code": error.get("code")}
    return {**error, "code": "internal", "details": details}


def _finish(job: Job, status: str, *, error: dict | None, message: str) -> None:
    job.status = status
    job.error = _known_code(error)
    job.message = message
    job.finished_at = utcnow()
    if status == "succeeded":
        job.progress = 1.0


def _fail_worker_lost(job: Job, max_attempts: int) -> None:
    _finish(job, "failed", message="worker lost", error={
        "code": "worker_lost",
        "message": f"the worker running this job died {max_attempts} times "
                   f"(killed, out of memory or crashed); giving up after {max_attempts} attempts"})


def finish(db: Database, job_id: str, attempt: int, *, status: str, result: dict | None,
           error: dict | None, message: str) -> bool:
    """Store the outcome (result first, in the same transaction) for the current token."""
    packed = None if result is None else storage.pack(result)  # compressed before the write lock is taken
    with db.write() as s:
        job = s.get(Job, job_id)
        if job is None or job.status != "running" or job.attempts != attempt:
            return False
        if packed is not None:
            storage.put_result(s, job, packed)
        _finish(job, status, error=error, message=message)
        return True


def reap_stale(db: Database, *, stale_after_s: float, max_attempts: int) -> list[Job]:
    """Re-queue running jobs whose heartbeat is older than ``stale_after_s``.

    Returns the re-queued jobs (new attempt token) to publish; jobs out of attempts fail.
    """
    cutoff = utcnow() - timedelta(seconds=stale_after_s)
    requeue: list[Job] = []
    with db.write() as s:
        stale = list(s.scalars(select(Job).where(Job.status == "running", Job.heartbeat_at < cutoff)))
        for job in stale:
            if job.attempts >= max_attempts:
                _fail_worker_lost(job, max_attempts)
                continue
            job.attempts += 1
            job.status = "queued"
            job.message = f"re-queued: worker heartbeat lost (attempt {job.attempts}/{max_attempts})"
            job.published_at = utcnow()
            requeue.append(job)
    return requeue
