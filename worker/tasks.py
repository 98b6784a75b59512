"""Celery tasks: deliver a job to its kind's ``run``; compute Monte Carlo chunks and a job's pieces.

Everything a test wants to exercise lives in :func:`execute_job` and in
``app.service.jobs``; the task functions only bind them to Celery.  Recovery (stale
jobs, lost messages) is not a task: it runs in ``app.service.recovery``'s own loop, so a
backlog in these queues never delays it.

A delivery that cannot reach the database is never acknowledged as done: the
task retries itself with backoff (a new message, same attempt token) until the
database answers, and a finished job whose result cannot be stored yet keeps
its result in memory and retries the write.
"""
from __future__ import annotations

import contextlib
import logging
import socket
import time

from celery import Task
from celery.exceptions import Ignore, SoftTimeLimitExceeded, TimeLimitExceeded
from sqlalchemy.exc import DBAPIError, OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeout

from app.runtime import logs
from app.service import jobs, metrics, studies
from app.service.broker import redis_client, time_limit_s
from app.service.recovery import publish_or_defer
from app.runtime.db import Database, get_database
from app.kinds import KINDS
from app.kinds.base import JobCancelled, JobFailure, RunOutcome
from app.runtime.settings import Settings, get_settings
from solvers.transcription import jit
from worker import fanout, pieces
from worker.celery_app import celery_app
from worker.context import WorkerJobContext
from worker.guard import DATA_BACKSTOP, MB, JobGuard

log = logging.getLogger("trajlab.worker")

DB_ERRORS = (OperationalError, DBAPIError, PoolTimeout)


class DatabaseUnavailable(Exception):
    """The job could not be claimed because the database did not answer: deliver it again later."""


@logs.isolated  # the job's log context ends with it
def execute_job(db: Database, settings: Settings, job_id: str, attempt: int, *, worker: str) -> str | None:
    """Claim, run and store one job. Returns the stored final status, None if this delivery was stale
    (never claimed), or :data:`REFUSED` if it ran but its result was not stored.

    Raises :class:`DatabaseUnavailable` when the claim cannot reach the database.
    """
    try:
        claim = jobs.claim(db, job_id, attempt, worker=worker, max_attempts=settings.max_attempts,
                           stale_after_s=settings.stale_after_s)
    except DB_ERRORS as exc:
        raise DatabaseUnavailable(type(exc).__name__) from None
    if claim is None:
        log.info("delivery of job %s attempt %d dropped (duplicate, stale or finished)", job_id, attempt)
        return None
    logs.bind(request_id=claim.request_id, job_id=job_id, kind=claim.kind, owner=claim.owner)
    started = time.monotonic()
    log.info("job %s attempt %d started (request %s)", job_id, claim.attempt, claim.request_id)
    spec = KINDS[claim.kind]
    ctx = WorkerJobContext(db, claim, settings=settings, celery=celery_app)
    guard = JobGuard(job_id=job_id, cap_bytes=_cap_bytes(settings), deadline=ctx.deadline,
                     grace_s=settings.hard_time_limit_margin_s / 2,
                     time_limit_message=_time_limit_error(settings, claim.kind,
                                                          ended_after_s=settings.hard_time_limit_margin_s / 2)["message"],
                     handler=BREACH_HANDLER, context={"attempt": claim.attempt})
    with ctx, guard:
        try:
            params = spec.params_model.model_validate(claim.params)
            with jit.expected_again() if claim.recurring else contextlib.nullcontext():
                outcome = spec.run(params, ctx)
        except MemoryError:  # a malloc refused by the guard's RLIMIT_DATA backstop
            outcome = RunOutcome("failed", error={"code": "resource_limit", "message": (
                f"the job ran out of memory: an allocation passed {DATA_BACKSTOP:g} times the cap of "
                f"{settings.job_memory_mb} MB per job (TRAJLAB_JOB_MEMORY_MB)")})
        except JobFailure as exc:
            outcome = RunOutcome("failed", error={"code": exc.code, "message": exc.message, "details": exc.details})
        except JobCancelled:
            outcome = RunOutcome("cancelled", error={"code": "cancelled", "message": "cancelled by request"})
        except SoftTimeLimitExceeded:
            outcome = RunOutcome("failed", error=_time_limit_error(settings, claim.kind))
        except Exception as exc:  # the job fails with a stored reason; the worker lives on
            log.exception("job %s crashed", job_id)
            # the type only: the text of an arbitrary exception can carry paths and addresses
            outcome = RunOutcome("failed", error={"code": "internal", "message": f"the solver raised "
                                                  f"{type(exc).__name__}; the worker log has the details"})
    if outcome.status == "cancelled" and not ctx.cancel_requested:
        # The solver stopped because should_stop() saw the deadline, not a user.
        outcome = RunOutcome("failed", result=outcome.result, error=_time_limit_error(settings, claim.kind))
    message = {"succeeded": "done", "cancelled": "cancelled"}.get(outcome.status) or (outcome.error or {}).get("message", "failed")
    stored = _store(db, settings, job_id, claim.attempt, outcome, message[:2000])
    if stored is not True:
        # Not this attempt's to move anything on: the attempt whose result is stored advances the study
        # (or the recovery loop's backstop does), so a study moves on once per point, not once per attempt.
        if stored is False:
            log.warning("job %s attempt %d refused: its %s result was not stored (the job was taken over by "
                        "another attempt, or finished or cancelled meanwhile)", job_id, claim.attempt, outcome.status)
        return REFUSED
    log.info("job %s attempt %d stored: %s (peak memory %.0f MB)", job_id, claim.attempt, outcome.status,
             guard.peak_bytes / MB)
    metrics.record_job(metrics.client(settings.broker_url), kind=claim.kind, duration_s=time.monotonic() - started,
                       queue_wait_s=claim.queue_wait_s, iterations=metrics.solver_iterations(outcome.result))
    for nxt in studies.on_point_finished(db, job_id):  # a study's next point (or a retry)
        publish_or_defer(db, celery_app, settings, nxt)
    return outcome.status


# What run_job returns for an attempt whose result was not stored (Celery logs the value it returns).
REFUSED = "refused (stale attempt, result not stored)"


def _store(db: Database, settings: Settings, job_id: str, attempt: int, outcome: RunOutcome,
           message: str) -> bool | None:
    """Store the outcome, retrying through a database outage for up to ``stale_after_s``: after that
    the reaper would hand the job to another worker anyway, and this result is dropped.  Each try is
    bounded by the database timeouts (app.runtime.db), so the slot is free within about
    ``stale_after_s + db_tcp_user_timeout_s + db_connect_timeout_s``.  True: stored; False: refused
    (this attempt no longer holds the job); None: the database never answered."""
    deadline = time.monotonic() + settings.stale_after_s
    delay = 0.5
    while True:
        try:
            return jobs.finish(db, job_id, attempt, status=outcome.status, result=outcome.result,
                               error=outcome.error, message=message)
        except DB_ERRORS as exc:
            if time.monotonic() + delay > deadline:
                log.error("job %s attempt %d: result not stored, database unreachable (%s); the reaper will "
                          "re-run it", job_id, attempt, type(exc).__name__)
                return None
            time.sleep(delay)
            delay = min(2 * delay, 5.0)


def _time_limit_error(settings: Settings, kind: str, *, ended_after_s: float | None = None) -> dict:
    """``ended_after_s``: the job did not stop by itself and its process was ended this long past the limit."""
    how = (f"; it did not stop within {ended_after_s:.0f} s (inside a native call), so its worker process was "
           "ended") if ended_after_s is not None else ""
    return {"code": "time_limit",
            "message": f"the {kind} job ran past its time limit of {time_limit_s(settings, kind):.0f} s "
                       f"(TRAJLAB_TIME_LIMIT_{kind.upper()}_S){how}"}


def _give_up(db: Database, settings: Settings, job_id: str, attempt: int, error: dict) -> None:
    """Store the failure of a job its guard ends (worker.guard: the process exits right after), and move
    its study on.  One try: a job past its memory cap must not hold the process while the database
    is away (the reaper takes the job over then)."""
    if jobs.finish(db, job_id, attempt, status="failed", result=None, error=error, message=error["message"][:2000]):
        for nxt in studies.on_point_finished(db, job_id):
            publish_or_defer(db, celery_app, settings, nxt)



# What a job's guard calls to store its breach (worker.guard: in the watcher process, after the job's
# process was ended): a module path, because the watcher is a process of its own.
BREACH_HANDLER = "worker.tasks:store_breach"


def store_breach(error: dict, context: dict) -> None:
    """Store the failure of the job ``context["job_id"]`` (attempt ``context["attempt"]``) that its guard
    ended; ``context["part"]`` names the share of its work that broke the bound (a Monte Carlo chunk or a
    piece run by another worker process)."""
    settings = get_settings()
    part = context.get("part")
    if part:
        error = {**error, "message": f"{error['message']} (in {part} of the job, run by another worker process)"}
    _give_up(get_database(settings.database_url, settings), settings, context["job_id"], int(context["attempt"]),
             error)


def _cap_bytes(settings: Settings) -> int | None:
    return settings.job_memory_mb * MB if settings.job_memory_mb else None


def _part_guard(settings: Settings, job: dict | None, part: str) -> contextlib.AbstractContextManager:
    """The guard of a share of a job's work that another worker process computes (a Monte Carlo chunk, a
    piece): the job's memory cap and what is left of its time limit; a breach fails the job.  ``job``
    (``{"id", "attempt", "ends_at"}``, ``ends_at`` a wall-clock time) comes with the work; without it (a
    message from before this field) the work runs unguarded, as it did."""
    if not job:
        return contextlib.nullcontext()
    grace_s = settings.hard_time_limit_margin_s / 2
    return JobGuard(job_id=job["id"], cap_bytes=_cap_bytes(settings),
                    deadline=time.monotonic() + (float(job["ends_at"]) - time.time()), grace_s=grace_s,
                    time_limit_message=f"the job ran past its time limit; this part of it did not stop within "
                                       f"{grace_s:.0f} s, so its worker process was ended",
                    handler=BREACH_HANDLER, context={"attempt": job["attempt"], "part": part})

class JobTask(Task):
    """``run_job``'s task class: a job whose process Celery's hard time limit killed is stored as failed."""

    def on_failure(self, exc, task_id, args, kwargs, einfo) -> None:
        # Celery calls this in the worker's main process after the hard limit killed the pool process (the
        # job's guard could not end it first: its thread needs the GIL, which a native call may hold).
        # Without it the job stayed running until the reaper re-ran it as if its worker had been lost.
        if not isinstance(exc, TimeLimitExceeded) or len(args) != 2:
            return
        settings = get_settings()
        db = get_database(settings.database_url, settings)
        job = jobs.get_job(db, args[0])
        if job is not None:
            _give_up(db, settings, job.id, int(args[1]),
                     _time_limit_error(settings, job.kind, ended_after_s=settings.hard_time_limit_margin_s))


@celery_app.task(name="trajlab.run_job", bind=True, max_retries=None, base=JobTask)
def run_job(self, job_id: str, attempt: int) -> str | None:
    settings = get_settings()
    try:
        status = execute_job(get_database(settings.database_url, settings), settings, job_id, attempt,
                             worker=self.request.hostname or socket.gethostname())
    except DatabaseUnavailable as exc:
        delay = min(2.0 ** min(self.request.retries, 6), settings.db_retry_max_s)
        log.warning("job %s: database unreachable (%s); delivery retried in %.0f s", job_id, exc, delay)
        raise self.retry(countdown=delay) from exc
    if status == REFUSED:
        # Acknowledged and logged by Celery as "ignored", not "succeeded": execute_job logged the refusal.
        raise Ignore()
    return status


@celery_app.task(name="trajlab.mc_chunk", bind=True)
def mc_chunk(self, run_id: str, index: int, start: int, count: int, seed: int) -> bool:
    settings = get_settings()
    return fanout.compute_chunk(redis_client(settings.broker_url, settings=settings), run_id, index, start, count,
                                seed, who=self.request.hostname or socket.gethostname(),
                                guarded=lambda job: _part_guard(settings, job, "a Monte Carlo chunk"))


@celery_app.task(name="trajlab.piece", bind=True)
def piece(self, run_id: str, index: int) -> bool:
    """One piece of a job's fan-out (``worker/pieces.py``), unless the job or another worker has it."""
    settings = get_settings()
    return pieces.compute_piece(redis_client(settings.broker_url, settings=settings), run_id, index,
                                who=self.request.hostname or socket.gethostname(),
                                guarded=lambda job: _part_guard(settings, job, "a piece"))
