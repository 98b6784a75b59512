"""The baseline for ``benchmarks.api_load``: the bare stack trajlab is built on, with nothing of trajlab.

A FastAPI app with one SQLAlchemy table: ``POST /v1/jobs`` commits a row and
publishes a Celery message (the job pattern: row first, then the message),
``GET /v1/jobs/{id}`` reads it back, ``GET /v1/jobs`` lists 20.  What trajlab
adds on top (validation of the kind's parameters, presets, owners, quotas,
idempotency, the re-publisher's mark) is what the ratio against this measures.

Run as ``python -m uvicorn benchmarks.api_baseline_app:app`` with
``BASELINE_DATABASE_URL`` and ``BASELINE_BROKER_URL`` set.
"""
from __future__ import annotations

import os
import uuid
from datetime import datetime, timezone

from celery import Celery
from fastapi import FastAPI, HTTPException
from pydantic import BaseModel
from sqlalchemy import JSON, DateTime, String, create_engine, select
from sqlalchemy.orm import DeclarativeBase, Mapped, Session, mapped_column


class Base(DeclarativeBase):
    pass


class BareJob(Base):
    __tablename__ = "bare_jobs"
    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    kind: Mapped[str] = mapped_column(String(32))
    status: Mapped[str] = mapped_column(String(16))
    params: Mapped[dict] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))


class Submission(BaseModel):
    kind: str
    preset: str | None = None
    params: dict | None = None


_url = os.environ["BASELINE_DATABASE_URL"]
# trajlab's pool size (app.runtime.db): with both apps up at 2 processes each, a larger baseline pool ran the shared
# PostgreSQL out of its 100 connections ("too many clients" errors at 100 wrk connections)
engine = create_engine(_url, pool_size=16, max_overflow=8) if not _url.startswith("sqlite") else create_engine(_url)
Base.metadata.create_all(engine)
celery = Celery("baseline", broker=os.environ["BASELINE_BROKER_URL"])
app = FastAPI()


def _out(job: BareJob) -> dict:
    return {"id": job.id, "kind": job.kind, "status": job.status, "params": job.params,
            "created_at": job.created_at.isoformat()}


@app.post("/v1/jobs", status_code=202)
def submit(body: Submission):
    job = BareJob(id=uuid.uuid4().hex, kind=body.kind, status="queued", params=body.params or {},
                  created_at=datetime.now(timezone.utc))
    with Session(engine, expire_on_commit=False) as s, s.begin():
        s.add(job)
    celery.send_task("baseline.run", args=[job.id], queue="baseline")
    return _out(job)


@app.get("/v1/jobs/{job_id}")
def get(job_id: str):
    with Session(engine) as s:
        job = s.get(BareJob, job_id)
        if job is None:
            raise HTTPException(404)
        return _out(job)


@app.get("/v1/jobs")
def list_(limit: int = 20):
    with Session(engine) as s:
        return {"items": [_out(j) for j in s.scalars(select(BareJob).order_by(BareJob.created_at.desc()).limit(limit))]}
