"""Admission: a new job or trade study goes from a request to queued rows and broker messages here, once.

The sequence is the same for a job and for every point of a study: resolve the parameters (preset, then
the caller's overrides, validated by the kind's model), check the warm starts, refuse a job past the
memory cap, estimate the cost, choose the queue, store the rows with the quota checked (the jobs table is
the truth), and only then hand the jobs to the process's publisher (app.service.publisher), which sends
their messages from its own thread: a request never waits on the broker, and a message the broker cannot
take leaves the job queued, kept and marked unpublished until the broker answers again.  The API routes translate HTTP to these calls and the exceptions back to status
codes (``app.api.errors``):

* :class:`app.service.params.InvalidParams`: a 422 naming ``body.params.<field>`` (bad parameters, a warm
  start that names no usable job);
* :class:`Refused`: a 422 with the message (memory cap, a bad sweep or study point, an Idempotency-Key
  reused for another request);
* :class:`app.service.quota.QuotaExceeded`: a 429 with ``Retry-After``.
"""
from __future__ import annotations

import logging

from app.kinds import KINDS, PRESETS
from app.runtime.db import Database
from app.runtime.models import Job, Study
from app.runtime.settings import Settings
from app.service import job_memory, jobs, quota, studies
from app.service.params import InvalidParams, resolve_params
from app.service.publisher import Publisher
from app.service.warm_start import check_warm_starts

log = logging.getLogger("trajlab.api")  # the API's line of each submission, as before the move


class Refused(Exception):
    """A submission that is not admitted, for the reason in ``message`` (a 422)."""

    def __init__(self, message: str):
        super().__init__(message)
        self.message = message


def _check_memory(kind: str, params: dict, settings: Settings, *, prefix: str = "") -> None:
    try:  # a job that cannot fit under the memory cap, refused before it is queued
        job_memory.check(kind, params, settings)
    except job_memory.OverMemoryCap as exc:
        raise Refused(prefix + exc.message) from None


def submit_job(db: Database, settings: Settings, publisher: Publisher, *, kind: str, preset: str | None,
               overrides: dict | None, label: str | None, owner: str | None,
               idempotency_key: str | None = None, request_hash: str | None = None,
               request_id: str | None = None) -> Job | jobs.JobRow:
    """Admit one job of ``owner`` (None: auth off, no quota) and hand it to ``publisher``; the job as stored.

    ``kind`` and ``preset`` are known names (the request schema checked them).  A repeated request
    (the same ``idempotency_key`` and ``request_hash``) returns the job it created, even at the quota.
    """
    spec = KINDS[kind]
    params = resolve_params(spec, PRESETS[preset].params if preset else None, overrides)
    _check_memory(kind, params, settings)
    check_warm_starts(db, kind=kind, params=params, owner=owner)
    cost = quota.estimate_cost(kind, params)
    # Quotas count new work only: repeating an accepted submission returns its job even at the limit
    # (create_job admits only a new job; lookup, quota and insert are one transaction).
    admit = None if owner is None else (lambda s: quota.check_quota_in(s, settings, owner=owner, cost=cost))
    try:
        job, created = jobs.create_job(db, kind=kind, params=params, label=label, preset=preset,
                                       idempotency_key=idempotency_key, request_hash=request_hash, owner=owner,
                                       queue=quota.queue_for(kind, cost, settings), admit=admit,
                                       request_id=request_id)
    except jobs.IdempotencyConflict:
        # draft-ietf-httpapi-idempotency-key-header: reuse with another payload is a 422.
        raise Refused("Idempotency-Key was already used for a different request body") from None
    if created:
        # the API's line of this request for the job; the worker logs the same request_id with the job's lines
        log.info("job %s submitted (kind %s, queue %s)", job.id, job.kind, job.queue)
        publisher.send([job])
    return job


def submit_study(db: Database, settings: Settings, publisher: Publisher, *, kind: str, preset: str | None,
                 overrides: dict | None, sweeps: list[dict], mode: str, label: str | None,
                 owner: str | None) -> Study:
    """Admit a trade study of ``owner``: every point must be a job this service would admit before
    anything is stored; the points to run now are published.  ``sweeps`` are validated sweeps
    (a path or paths and values or a range)."""
    spec = KINDS[kind]
    base = resolve_params(spec, PRESETS[preset].params if preset else None, overrides)
    check_warm_starts(db, kind=kind, params=base, owner=owner)
    try:
        points = studies.expand(base, sweeps)
    except KeyError as exc:
        raise Refused(f"sweeps: {exc.args[0]}") from None
    if len(points) > studies.MAX_POINTS:
        raise Refused(f"a study has at most {studies.MAX_POINTS} points")
    for p in points:  # every point must be a valid job before anything is stored
        where = f"point {p.index} ({p.values}): "
        try:
            p.params = resolve_params(spec, p.params, None)
        except InvalidParams as exc:
            raise Refused(where + "; ".join(f"{'.'.join(map(str, e['loc'][1:]))}: {e['msg']}"
                                            for e in exc.errors)) from None
        _check_memory(kind, p.params, settings, prefix=where)
    # A study is as much work as its points: an independent one queues all of them at once, a
    # continuation one runs one at a time, so it is charged its dearest point.
    costs = [quota.estimate_cost(kind, p.params) for p in points]
    quota.check_quota(db, settings, owner=owner, cost=sum(costs) if mode == "independent" else max(costs))
    study, created = studies.create_study(db, kind=kind, preset=preset, label=label, base_params=base,
                                          sweeps=sweeps, mode=mode, points=points, owner=owner,
                                          queue=quota.queue_for(kind, max(costs), settings))
    publisher.send(created)
    return study
