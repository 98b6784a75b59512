"""Who is asking, and which jobs they may see: the one seam every job route goes through.

Every route that reads or changes a job (get, result, cancel, events, plots,
reports, files) takes a :data:`PrincipalDep` and loads the job with
:func:`visible_job`, so owner isolation is decided in one place: a job of
another owner is a 404, exactly like a job that does not exist.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, HTTPException, Request

from app import jobs
from app.db import Database
from app.models import Job


@dataclass(frozen=True)
class Principal:
    """The caller: ``owner`` None with ``admin`` True is the auth-off local user, who sees everything."""

    owner: str | None
    admin: bool = False

    def may_see(self, job: Job) -> bool:
        return self.admin or (job.owner is not None and job.owner == self.owner)


LOCAL = Principal(owner=None, admin=True)


def _principal(request: Request) -> Principal:
    return LOCAL


PrincipalDep = Annotated[Principal, Depends(_principal)]


def not_found(job_id: str) -> HTTPException:
    return HTTPException(status_code=404, detail=f"job {job_id} not found")


def visible_job(db: Database, job_id: str, principal: Principal) -> Job:
    """The job if this caller may see it; otherwise a 404 (never a 403: existence is not disclosed)."""
    job = jobs.get_job(db, job_id)
    if job is None or not principal.may_see(job):
        raise not_found(job_id)
    return job
