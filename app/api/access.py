"""Who is asking, and which jobs they may see: the one seam every job route goes through.

Every route that reads or changes a job (get, result, cancel, events, plots,
reports, files) takes a :data:`PrincipalDep` and loads the job with
:func:`visible_job`, so owner isolation is decided in one place: a job of
another owner is a 404, exactly like a job that does not exist.

With ``TRAJLAB_AUTH=required`` the caller is the owner of the API key in
``Authorization: Bearer KEY`` (:mod:`app.api.auth`); a missing, unknown or revoked
key is a 401.  With ``off`` every caller is :data:`LOCAL`, who sees every job.
FastAPI's ``HTTPBearer`` declares the scheme, so ``/docs`` has the Authorize button.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Annotated, Protocol

from fastapi import Depends, HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from app.api import auth, key_attempts
from app.api.observability import AUTH_FAILURES
from app.service import jobs
from app.runtime.db import Database


class Owned(Protocol):
    """A job, a job's row or a study: what has an owner."""

    @property
    def owner(self) -> str | None: ...


@dataclass(frozen=True)
class Principal:
    """The caller: ``owner`` None with ``admin`` True is the auth-off local user, who sees everything."""

    owner: str | None
    admin: bool = False

    def may_see(self, job: Owned) -> bool:
        return self.admin or (job.owner is not None and job.owner == self.owner)

    @property
    def owner_filter(self) -> str | None:
        """The owner a listing is restricted to; None (everything) for admins and LOCAL."""
        return None if self.admin else self.owner


LOCAL = Principal(owner=None, admin=True)

bearer_scheme = HTTPBearer(auto_error=False, description="An API key from `trajlab keys create` (TRAJLAB_AUTH=required)")


def _unauthorized(detail: str, *, error: str | None = None) -> HTTPException:
    challenge = "Bearer" if error is None else f'Bearer error="{error}"'  # RFC 6750 section 3
    return HTTPException(status_code=401, detail=detail, headers={"WWW-Authenticate": challenge})


async def _principal(request: Request,
                     credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer_scheme)]) -> Principal:
    # async, so auth off costs no thread-pool hop; the key lookup (database) runs in the pool
    if request.app.state.settings.auth == "off":
        return LOCAL
    return await run_in_threadpool(_key_principal, request, credentials)


def _key_principal(request: Request, credentials: HTTPAuthorizationCredentials | None) -> Principal:
    if credentials is None:
        raise _unauthorized("an API key is required: Authorization: Bearer KEY")
    # the key first: a valid key is never refused for what others sent from its address (app.api.key_attempts)
    key = auth.authenticate(request.app.state.db, credentials.credentials)
    if key is not None:
        return Principal(owner=key.owner, admin=key.admin)
    attempts = key_attempts.for_app(request.app.state, request.app.state.settings)
    # the peer, or a trusted proxy's X-Forwarded-For (TRAJLAB_TRUSTED_PROXIES, read in app.api.main)
    address = request.client.host if request.client is not None else ""
    wait_s = attempts.retry_after_s(address)
    if wait_s is not None:
        AUTH_FAILURES.labels("refused").inc()
        raise HTTPException(status_code=429, headers={"Retry-After": str(wait_s)},
                            detail=f"too many failed API-key attempts from this address; retry in {wait_s} s")
    attempts.failed(address)
    AUTH_FAILURES.labels("invalid").inc()
    raise _unauthorized("unknown or revoked API key", error="invalid_token")


PrincipalDep = Annotated[Principal, Depends(_principal)]


async def principal_before_body(request: Request) -> Principal:
    """The same check for a route that wants to refuse a caller before reading a large body
    (FastAPI reads and parses the body before it runs dependencies)."""
    return await _principal(request, await bearer_scheme(request))


_JOB_ID = re.compile(r"[0-9a-f]{32}")  # app.runtime.models.new_id: uuid4().hex


def not_found(job_id: str) -> HTTPException:
    return HTTPException(status_code=404, detail=f"job {job_id} not found")


def visible_job(db: Database, job_id: str, principal: Principal) -> jobs.JobRow:
    """The job's columns if this caller may see it; otherwise a 404 (never a 403: existence is not disclosed)."""
    if not _JOB_ID.fullmatch(job_id):  # not an id we issue (e.g. a NUL, which PostgreSQL refuses): no query
        raise not_found(job_id[:40])
    job = jobs.get_job_row(db, job_id)
    if job is None or not principal.may_see(job):
        raise not_found(job_id)
    return job
