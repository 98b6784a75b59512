"""Celery tasks: deliver a job to its kind's ``run``, and reap jobs of dead workers.

Everything a test wants to exercise lives in :func:`execute_job` and in
``app.jobs``; the task functions only bind them to Celery.
"""
from __future__ import annotations

import logging
import socket

from celery.exceptions import SoftTimeLimitExceeded

from app import jobs, studies
from app.db import Database, get_database
from app.kinds import KINDS
from app.kinds.base import JobCancelled, JobFailure, RunOutcome
from app.settings import Settings, get_settings
from worker import fanout
from worker.celery_app import celery_app, publish_job
from worker.context import WorkerJobContext

log = logging.getLogger("trajlab.worker")


def execute_job(db: Database, settings: Settings, job_id: str, attempt: int, *, worker: str) -> str | None:
    """Claim, run and store one job. Returns the final status, or None if this delivery was stale."""
    claim = jobs.claim(db, job_id, attempt, worker=worker, max_attempts=settings.max_attempts)
    if claim is None:
        return None
    spec = KINDS[claim.kind]
    ctx = WorkerJobContext(db, claim, settings=settings, celery=celery_app)
    with ctx:
        try:
            params = spec.params_model.model_validate(claim.params)
            outcome = spec.run(params, ctx)
        except JobFailure as exc:
            outcome = RunOutcome("failed", error={"code": exc.code, "message": exc.message, "details": exc.details})
        except JobCancelled:
            outcome = RunOutcome("cancelled", error={"code": "cancelled", "message": "cancelled by request"})
        except SoftTimeLimitExceeded:
            outcome = RunOutcome("failed", error=_time_limit_error(settings, claim.kind))
        except Exception as exc:  # the job fails with a stored reason; the worker lives on
            log.exception("job %s crashed", job_id)
            outcome = RunOutcome("failed", error={"code": "internal", "message": f"{type(exc).__name__}: {exc}"})
    if outcome.status == "cancelled" and not ctx.cancel_requested:
        # The solver stopped because should_stop() saw the deadline, not a user.
        outcome = RunOutcome("failed", result=outcome.result, error=_time_limit_error(settings, claim.kind))
    message = {"succeeded": "done", "cancelled": "cancelled"}.get(outcome.status) or (outcome.error or {}).get("message", "failed")
    jobs.finish(db, job_id, claim.attempt, status=outcome.status, result=outcome.result,
                error=outcome.error, message=message[:2000])
    for nxt in studies.on_point_finished(db, job_id):  # a continuation study's next point
        publish_job(celery_app, settings, job_id=nxt.id, attempt=nxt.attempts, kind=nxt.kind, queue=nxt.queue)
    return outcome.status


def _time_limit_error(settings: Settings, kind: str) -> dict:
    return {"code": "time_limit",
            "message": f"the {kind} job ran past its time limit of {settings.time_limit_s(kind):.0f} s "
                       f"(TRAJLAB_TIME_LIMIT_{kind.upper()}_S)"}


@celery_app.task(name="trajlab.run_job", bind=True)
def run_job(self, job_id: str, attempt: int) -> str | None:
    settings = get_settings()
    return execute_job(get_database(settings.database_url), settings, job_id, attempt,
                       worker=self.request.hostname or socket.gethostname())


@celery_app.task(name="trajlab.mc_chunk", bind=True)
def mc_chunk(self, run_id: str, index: int, start: int, count: int, seed: int) -> bool:
    settings = get_settings()
    return fanout.compute_chunk(fanout.redis_from_broker_url(settings.broker_url), run_id, index, start, count,
                                seed, who=self.request.hostname or socket.gethostname())


@celery_app.task(name="trajlab.reap")
def reap() -> int:
    settings = get_settings()
    requeue = jobs.reap_stale(get_database(settings.database_url),
                              stale_after_s=settings.stale_after_s, max_attempts=settings.max_attempts)
    for job_id, attempt, kind in requeue:
        publish_job(celery_app, settings, job_id=job_id, attempt=attempt, kind=kind)
        log.warning("re-queued job %s (attempt %d) after its heartbeat went stale", job_id, attempt)
    return len(requeue)
