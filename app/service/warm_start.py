"""Warm starts checked at the door: a ``from_job`` must name a job the new one can start from.

Every kind that takes a warm start names the job in a field called ``from_job``
(``initial_guess.from_job`` in every kind, and in any nested group a kind may add, e.g. per phase).  Before anything is stored,
each such field of the resolved parameters must name a job that

* exists and the caller may read: the worker's rule (``worker/context.py``): a job
  reads only its own owner's results, and with auth off every job is everyone's;
  another owner's job gets the same answer as an unknown one (existence is not
  disclosed);
* is of the same kind (a reentry result is not an intercept guess);
* has succeeded (a failed or unfinished job has no answer to start from);
* fits, where the kind says what fits (``KindSpec.warm_start_misfit``: an ``ocp`` problem of several
  phases starts only from a result with the same phases).

Anything else is a 422 naming ``params.<path>`` and the reason, instead of a job
that is accepted and later fails.
"""
from __future__ import annotations

import re
from typing import Iterator

from app.runtime.db import Database
from app.service import jobs
from app.service.params import InvalidParams

FIELD = "from_job"
_JOB_ID = re.compile(r"[0-9a-f]{32}")  # the ids we issue; anything else is looked up nowhere


def warm_start_fields(params, path: tuple = ()) -> Iterator[tuple[tuple, str]]:
    """``(path, job id)`` of every non-null ``from_job`` inside the parameters (dicts and lists, any depth)."""
    if isinstance(params, dict):
        for key, value in params.items():
            if key == FIELD and isinstance(value, str):
                yield (*path, key), value
            else:
                yield from warm_start_fields(value, (*path, key))
    elif isinstance(params, list):
        for i, value in enumerate(params):
            yield from warm_start_fields(value, (*path, i))


def _reason(db: Database, job_id: str, *, kind: str, owner: str | None) -> str | None:
    job = jobs.get_job_row(db, job_id) if _JOB_ID.fullmatch(job_id) else None
    if job is None or not (owner is None or job.owner == owner):
        return f"job {job_id[:64]} does not exist"
    if job.kind != kind:
        return f"job {job_id} is a {job.kind} job; a warm start needs a {kind} job"
    if job.status != "succeeded":
        return f"job {job_id} is {job.status}; only a succeeded job can be a warm start"
    return None


def _misfit(db: Database, job_id: str, *, kind: str, params: dict) -> str | None:
    from app.kinds import KINDS

    spec = KINDS.get(kind)
    check = spec.warm_start_misfit if spec is not None else None
    if check is None:
        return None
    stored = jobs.get_result(db, job_id)
    return check(stored, params) if isinstance(stored, dict) else None


def check_warm_starts(db: Database, *, kind: str, params: dict, owner: str | None) -> None:
    """Raise :class:`InvalidParams` (a 422) for every ``from_job`` that names no job ``owner`` (None: auth
    off, every job is everyone's) can start from."""
    errors = []
    for path, job_id in warm_start_fields(params):
        reason = _reason(db, job_id, kind=kind, owner=owner) or \
            _misfit(db, job_id, kind=kind, params=params)
        if reason is not None:
            errors.append({"loc": ("params", *path), "msg": reason, "type": "warm_start", "input": job_id})
    if errors:
        raise InvalidParams(errors)
