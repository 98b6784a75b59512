"""A job as the API's JSON document (``schemas.JobOut``'s fields, in its order): written here once, for the
job routes (which return the bytes directly) and for the listing (which splices each row's stored params in)."""
from __future__ import annotations

import json
from datetime import datetime, timezone
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from app.runtime.models import Job


def _iso(dt: datetime | None) -> str | None:
    """ISO 8601 in UTC with a ``Z``, as pydantic writes a UTC datetime (the job's JSON never changes form)."""
    if dt is None:
        return None
    if dt.tzinfo is None:  # SQLite returns naive datetimes; every stored time is UTC
        dt = dt.replace(tzinfo=timezone.utc)
    text = dt.astimezone(timezone.utc).isoformat()
    return text[:-6] + "Z" if text.endswith("+00:00") else text


def _error(error: dict | None) -> dict | None:
    # the fields of schemas.JobError, in its order ("details" null when not stored)
    return None if error is None else {"code": error.get("code"), "message": error.get("message"),
                                       "details": error.get("details")}


def stage_of(job) -> dict | None:
    """The stage a job announced (``schemas.JobStage``), as the job document and its event stream give it."""
    return None if job.stage is None else {"name": job.stage, "round": job.stage_round}


def job_to_dict(job: Job) -> dict:
    """The job document of the API (``schemas.JobOut``'s fields, in its order, JSON-ready)."""
    return _document(job, job.params)


def _document(job, params) -> dict:
    return {
        "id": job.id,
        "kind": job.kind,
        "label": job.label,
        "preset": job.preset,
        "status": job.status,
        "progress": job.progress,
        "message": job.message,
        "stage": stage_of(job),
        "created_at": _iso(job.created_at),
        "started_at": _iso(job.started_at),
        "finished_at": _iso(job.finished_at),
        "params": params,
        "error": _error(job.error),
        "attempts": job.attempts,
    }


def job_json(job: Job) -> bytes:
    """The job document as JSON bytes, the body routes return directly: the same document FastAPI
    wrote through ``response_model=JobOut`` (tests/unit/test_job_json.py), without validating it again
    in a thread-pool hop."""
    return json.dumps(job_to_dict(job), allow_nan=False, separators=(",", ":")).encode()


def listed_job_json(row) -> str:
    # The params go out as the database stores them (JSON text written by SQLAlchemy from a validated,
    # finite model dump): parsing and re-writing 20 of them was a third of a listing's CPU.
    head, tail = json.dumps(_document(row, None), allow_nan=False, separators=(",", ":")).split(',"params":null,', 1)
    return f'{head},"params":{row.params_json},{tail}'
