"""SQLAlchemy models: the jobs table is the truth; results live in their own table.

Results (trajectories, scans, Pareto fronts) are kilobytes to megabytes of JSON
that only ``GET /result`` and warm starts read; keeping them out of ``jobs``
keeps job listing and the worker's frequent progress/heartbeat updates on small
rows.  The arrays stay inside the JSON document rather than in a point table:
they are always read whole, never queried element by element.
"""
from __future__ import annotations

import uuid
from datetime import datetime, timezone

from sqlalchemy import (JSON, BigInteger, Boolean, DateTime, Float, ForeignKey, Index, Integer, LargeBinary, MetaData,
                        String, Text)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}

JOB_STATUSES = ("queued", "running", "succeeded", "failed", "cancelled")
FINAL_STATUSES = ("succeeded", "failed", "cancelled")


def utcnow() -> datetime:
    return datetime.now(timezone.utc)


def new_id() -> str:
    return uuid.uuid4().hex


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING_CONVENTION)


class Job(Base):
    __tablename__ = "jobs"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    kind: Mapped[str] = mapped_column(String(32))
    label: Mapped[str | None] = mapped_column(String(200))
    preset: Mapped[str | None] = mapped_column(String(100))
    status: Mapped[str] = mapped_column(String(16), default="queued")
    progress: Mapped[float] = mapped_column(Float, default=0.0)
    message: Mapped[str] = mapped_column(Text, default="")
    # the stage the running job announced (solvers.progress) and its round number: the API's ``stage``
    stage: Mapped[str | None] = mapped_column(String(200))
    stage_round: Mapped[int | None] = mapped_column(Integer)
    params: Mapped[dict] = mapped_column(JSON)
    error: Mapped[dict | None] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    heartbeat_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    worker: Mapped[str | None] = mapped_column(String(200))
    idempotency_key: Mapped[str | None] = mapped_column(String(200), unique=True)
    request_hash: Mapped[str | None] = mapped_column(String(64))
    # When the current attempt's message was last handed to the broker; None
    # while it could not be (broker down at submission): the re-publisher sends
    # every queued job that is unpublished or published long ago and unclaimed.
    published_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    # The broker queue its messages go to (app.service.broker.QUEUES), chosen at submission.
    queue: Mapped[str] = mapped_column(String(32), default="trajlab.jobs", server_default="trajlab.jobs")
    # The owner (API key owner) the job belongs to; None when auth is off.
    owner: Mapped[str | None] = mapped_column(String(100))
    # The X-Request-ID of the submission (app.runtime.logs): the worker logs it with the job's lines.
    request_id: Mapped[str | None] = mapped_column(String(128))
    # A point of a trade study (app/service/studies.py): the study and the point's index in it.
    study_id: Mapped[str | None] = mapped_column(ForeignKey("studies.id", ondelete="SET NULL"))
    study_index: Mapped[int | None] = mapped_column(Integer)
    # Bytes this job keeps in the database: its params' JSON plus its result as stored (compressed),
    # kept up to date on every write of either, so GET /v1/usage and the storage quota sum a column
    # instead of reading results (app.service.storage).
    stored_bytes: Mapped[int] = mapped_column(BigInteger, default=0, server_default="0")

    __table_args__ = (
        Index("ix_jobs_created_at", "created_at"),
        Index("ix_jobs_status_kind", "status", "kind"),
        Index("ix_jobs_owner_created_at", "owner", "created_at"),
        Index("ix_jobs_study_id", "study_id"),
        # retention and `trajlab purge`: finished jobs by status, oldest first
        Index("ix_jobs_status_finished_at", "status", "finished_at"),
    )


class StoredResult(Base):
    """A job's result document as stored (the row; the typed body the API serves is
    ``app.api.result_body.JobResult``, the union of the kinds' result models).  Written compressed (``packed``, in the form ``encoding`` names:
    app.runtime.result_codec); rows written before revision 0006 hold it as JSON in ``data``, and are
    read as they are (never rewritten in bulk)."""

    __tablename__ = "job_results"

    job_id: Mapped[str] = mapped_column(ForeignKey("jobs.id", ondelete="CASCADE"), primary_key=True)
    data: Mapped[dict | None] = mapped_column(JSON)
    packed: Mapped[bytes | None] = mapped_column(LargeBinary)
    encoding: Mapped[str | None] = mapped_column(String(16))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class ApiKey(Base):
    """An API key: only the SHA-256 of the key is stored (app.api.auth); the key itself is shown once."""

    __tablename__ = "api_keys"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    name: Mapped[str] = mapped_column(String(100), unique=True)
    # Jobs submitted with this key belong to ``owner`` (several keys may share one owner).
    owner: Mapped[str] = mapped_column(String(100))
    key_hash: Mapped[str] = mapped_column(String(64), unique=True)
    # The first characters of the key (e.g. "tl_Ab3x"), so a listing can tell keys apart.
    key_prefix: Mapped[str] = mapped_column(String(16))
    admin: Mapped[bool] = mapped_column(Boolean, default=False)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    revoked_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    last_used_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))


class Study(Base):
    """A trade study: a base job swept over one or two parameters (app/service/studies.py)."""

    __tablename__ = "studies"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    kind: Mapped[str] = mapped_column(String(32))
    label: Mapped[str | None] = mapped_column(String(200))
    preset: Mapped[str | None] = mapped_column(String(100))
    mode: Mapped[str] = mapped_column(String(16))
    status: Mapped[str] = mapped_column(String(16), default="running")
    base_params: Mapped[dict] = mapped_column(JSON)
    sweeps: Mapped[list] = mapped_column(JSON)
    # every point's swept values and resolved params, fixed at submission
    points: Mapped[list] = mapped_column(JSON)
    # where a continuation walk stands: {"phase": "forward"|"backward", "cursor": i}
    walk: Mapped[dict] = mapped_column(JSON)
    owner: Mapped[str | None] = mapped_column(String(100))
    queue: Mapped[str] = mapped_column(String(32), default="trajlab.jobs", server_default="trajlab.jobs")
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))

    __table_args__ = (Index("ix_studies_owner_created_at", "owner", "created_at"),)


class Lease(Base):
    """A named duty at most one process performs at a time (app.service.lease): the recovery loop's
    reaper, re-publisher, studies and retention run in every worker, and the holder of the row named
    ``recovery`` does them.  ``renewed_at`` is the recovery heartbeat ``/readyz`` reads."""

    __tablename__ = "leases"

    name: Mapped[str] = mapped_column(String(64), primary_key=True)
    holder: Mapped[str | None] = mapped_column(String(200))
    acquired_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    renewed_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True))
    # free when in the past: a candidate takes it; the holder pushes it forward on each renewal
    expires_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
