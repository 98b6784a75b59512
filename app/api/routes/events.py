"""``GET /v1/jobs/{id}/events``: a job's progress as Server-Sent Events.

The job row stays the truth: each open stream reads it once per heartbeat
interval (the rate at which a worker writes progress, so polling faster would
only re-read the same row), sends an event when status, progress, message or
attempt changed, and closes after the event that reports a final status.

Event ids encode the state they report, not a counter: a client that
reconnects with ``Last-Event-ID`` gets the next *change* after that state, so
no event is repeated and none needs to be stored.  FastAPI's SSE support sends
a ``: ping`` comment every 15 s while nothing changes (keep-alive for proxies).
"""
from __future__ import annotations

import asyncio
import zlib
from typing import Annotated, AsyncIterator

from fastapi import APIRouter, Depends, Header
from fastapi.concurrency import run_in_threadpool
from fastapi.sse import EventSourceResponse, ServerSentEvent

from app.service import jobs
from app.service.job_document import stage_of
from app.api.access import PrincipalDep, visible_job
from app.api.deps import DatabaseDep, SettingsDep
from app.runtime.models import FINAL_STATUSES, JOB_STATUSES, Job

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])

RETRY_MS = 2000  # how long a browser waits before it reconnects after a dropped stream


def state_id(job: Job) -> str:
    """An event id that names the reported state: status rank, progress, attempt, message digest."""
    digest = zlib.crc32((job.message or "").encode("utf-8", "replace"))
    return f"{JOB_STATUSES.index(job.status)}.{round(job.progress * 1e6)}.{job.attempts}.{digest:08x}"


def event_of(job: Job) -> ServerSentEvent:
    final = job.status in FINAL_STATUSES
    data = {"id": job.id, "status": job.status, "progress": job.progress, "message": job.message,
            "stage": stage_of(job),
            "attempts": job.attempts, "error": job.error}
    return ServerSentEvent(event="end" if final else "progress", id=state_id(job), data=data, retry=RETRY_MS)


def _job(job_id: str, db: DatabaseDep, principal: PrincipalDep) -> Job:
    # A dependency, so an unknown or foreign job is a 404 before the stream starts.
    return visible_job(db, job_id, principal)


@router.get("/{job_id}/events", response_class=EventSourceResponse, operation_id="job_events",
            responses={200: {"description": "`text/event-stream`: `progress` events, then one `end` event "
                                            "carrying the final status"},
                       404: {"description": "Unknown job"}})
async def job_events(job: Annotated[Job, Depends(_job)], db: DatabaseDep, settings: SettingsDep,
                     last_event_id: Annotated[str | None, Header(max_length=100)] = None
                     ) -> AsyncIterator[ServerSentEvent]:
    """Follow a job live. Reconnect with `Last-Event-ID` to continue without repeats."""
    interval = max(float(settings.heartbeat_interval_s), 0.2)
    sent = last_event_id
    current: Job | None = job
    while current is not None:
        if state_id(current) != sent:
            sent = state_id(current)
            yield event_of(current)
        if current.status in FINAL_STATUSES:
            return
        await asyncio.sleep(interval)
        current = await run_in_threadpool(jobs.get_job, db, current.id)
