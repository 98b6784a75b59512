"""/v1/jobs: submit, list, get, result, cancel, delete."""
from __future__ import annotations

import hashlib
import json
from typing import Annotated, Literal

from fastapi import APIRouter, Body, Header, HTTPException, Query, Request, Response
from fastapi.responses import JSONResponse

from app.service import job_document, jobs, retention, submit
from app.api.access import PrincipalDep, not_found, visible_job
from app.api.deps import DatabaseDep
from app.kinds import KINDS
from app.api.submit_examples import job_examples
from app.results.compact import compact
from app.api.result_body import JobResult, result_json
from app.api.routes.results import forget
from app.api.schemas import (ErrorBody, JobList, JobOut, JobStatus, JobSubmission, NotSucceededBody,
                             ValidationErrorBody)
from app.runtime import logs

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])
# The hot routes (submit, list, get) read the database, settings and broker from request.app.state
# instead of app.api.deps' dependencies: FastAPI solves every dependency on every request, about 5% of a
# GET's CPU each (measured with py-spy); the principal stays a dependency (OpenAPI's security scheme).


def _job_response(body: bytes, *, status_code: int = 200, headers: dict | None = None) -> Response:
    """A job document already serialized (app.service.jobs.job_json): ``response_model`` stays for the OpenAPI
    document, and FastAPI neither validates nor serializes the returned dict again (for a ``def`` route
    that is one more thread-pool hop per request)."""
    return Response(body, status_code=status_code, headers=headers, media_type="application/json")


@router.post("", status_code=202, response_model=JobOut,
             responses={202: {"description": "Accepted: the job is queued; `Location` points at it",
                              "headers": {"Location": {"description": "/v1/jobs/{id} of the new job",
                                                       "schema": {"type": "string"}}}},
                        422: {"model": ValidationErrorBody, "description": "Invalid parameters (the message names the field and the rule), "
                                              "a job estimated past the memory cap (TRAJLAB_JOB_MEMORY_MB), "
                                              "or an Idempotency-Key reused for a different request"},
                        429: {"description": "Over the owner's quota of queued/running jobs or estimated cost; "
                                              "`Retry-After` says when to try again"},
                        503: {"description": "The database could not be reached (`Retry-After` says when to "
                                              "try again); nothing was stored"}})
def submit_job(
    submission: Annotated[JobSubmission, Body(openapi_examples=job_examples())],
    request: Request, principal: PrincipalDep,
    idempotency_key: Annotated[str | None, Header(max_length=200, description="Repeat a submission safely: the same key and body return the same job")] = None,
):
    request_hash = None
    if idempotency_key is not None:
        body = submission.model_dump(mode="json", exclude_unset=True)
        request_hash = hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()
    # app.service.submit admits it; its refusals are 422s and 429s (app.api.errors)
    job = submit.submit_job(
        request.app.state.db, request.app.state.settings, request.app.state.publisher, kind=submission.kind,
        preset=submission.preset, label=submission.label, owner=principal.owner,
        overrides=submission.params.model_dump(exclude_unset=True) if submission.params is not None else None,
        idempotency_key=idempotency_key, request_hash=request_hash, request_id=logs.current("request_id"))
    return _job_response(job_document.job_json(job), status_code=202, headers={"Location": f"/v1/jobs/{job.id}"})


@router.get("", response_model=JobList)
def list_jobs(
    request: Request, principal: PrincipalDep,
    kind: Annotated[str | None, Query(description="Only this kind")] = None,
    status: Annotated[JobStatus | None, Query(description="Only this status")] = None,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    # bounded: SQLite and PostgreSQL take a signed 64-bit OFFSET, and a larger one was a 500
    offset: Annotated[int, Query(ge=0, le=2**62)] = 0,
):
    if kind is not None and kind not in KINDS:
        raise HTTPException(status_code=422, detail=f"kind must be one of {sorted(KINDS)}")
    return _job_response(jobs.list_jobs_json(request.app.state.db, kind=kind, status=status, limit=limit, offset=offset,
                                             owner=principal.owner_filter))


@router.get("/{job_id}", response_model=JobOut, responses={404: {"model": ErrorBody, "description": "Unknown job"}})
def get_job(job_id: str, request: Request, principal: PrincipalDep):
    return _job_response(job_document.job_json(visible_job(request.app.state.db, job_id, principal)))


@router.get("/{job_id}/result", response_model=JobResult, responses={
    200: {"description": "The result: one of the kinds' result models (fields and units in each schema)"},
    404: {"model": ErrorBody, "description": "Unknown job"},
    409: {"model": NotSucceededBody, "description": "Not succeeded (yet): the body gives the status, the error and any stored diagnostic "
                         "or partial result (e.g. the Pareto front of a cancelled run)"}})
def get_result(job_id: str, db: DatabaseDep, principal: PrincipalDep,
               include: Annotated[list[Literal["scan", "samples"]], Query(
                   description="Full arrays the default body thins: `scan` (intercept delta-v scan), "
                               "`samples` (robust Monte Carlo sample traces)")] = [],  # noqa: B006 (FastAPI copies it per request)
               if_none_match: Annotated[str | None, Header(max_length=200)] = None):
    job = visible_job(db, job_id, principal)
    result = jobs.get_result(db, job_id) if job.status in ("succeeded", "failed", "cancelled") else None
    if job.status != "succeeded":
        return JSONResponse(status_code=409, content={
            "detail": f"job {job_id} is {job.status}; its result is available once it has succeeded",
            "status": job.status, "error": job.error, "partial_result": result})
    # a succeeded result never changes: a strong validator per job and view, and a long private cache
    etag = f'"{job_id}-result-{"-".join(sorted(set(include))) or "default"}"'
    headers = {"ETag": etag, "Cache-Control": "private, max-age=86400"}
    if if_none_match and etag in [t.strip() for t in if_none_match.split(",")]:
        return Response(status_code=304, headers=headers)
    assert result is not None  # the worker stores a succeeded job's result with its status (jobs.finish)
    # validated by the kind's model and written by pydantic-core (app.api.result_body.result_json)
    return Response(result_json(job.kind, compact(job.kind, result, set(include))), media_type="application/json",
                    headers=headers)


@router.delete("/{job_id}", status_code=204, response_class=Response,
               responses={204: {"description": "Deleted: the job, its result and its cached files are gone; "
                                               "the job is 404 from now on"},
                          404: {"model": ErrorBody, "description": "Unknown job (or another owner's)"},
                          409: {"model": ErrorBody, "description": "A point of a trade study: a study is deleted "
                                                                   "whole (`DELETE /v1/studies/{id}`)"}})
def delete_job(job_id: str, db: DatabaseDep, principal: PrincipalDep) -> Response:
    """Delete a job with its result, by its owner or an admin. A queued or running job is cancelled
    first (its worker stops at the next heartbeat and stores nothing)."""
    job = visible_job(db, job_id, principal)
    if job.study_id is not None:  # a study missing a point would wait for it for ever
        raise HTTPException(status_code=409, detail=f"job {job_id} is a point of study {job.study_id}; delete the "
                                                    f"study with its points (DELETE /v1/studies/{job.study_id})")
    if not retention.delete_job(db, job_id):
        raise not_found(job_id)
    forget([job_id])
    return Response(status_code=204)


@router.post("/{job_id}/cancel", status_code=202, response_model=JobOut, responses={404: {"model": ErrorBody, "description": "Unknown job"}})
def cancel_job(job_id: str, db: DatabaseDep, principal: PrincipalDep):
    visible_job(db, job_id, principal)
    job = jobs.request_cancel(db, job_id)
    if job is None:
        raise not_found(job_id)
    return _job_response(job_document.job_json(job), status_code=202)
