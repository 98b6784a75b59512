"""What the console's job page and job list lead with: the headline numbers a kind declares
(app.kinds.headlines) and, for a failed job, its explanation (app.kinds.failures) with the plots of the
last iterate the solver stored; and the parameter schema the New job form is generated from.  Every route loads jobs through ``visible_job`` (owner isolation), as
the public ``/v1`` routes do; none is part of the API document (the console's own plumbing).
"""
from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response

from app.api.access import PrincipalDep, visible_job
from app.api.deps import DatabaseDep
from app.kinds.failures import as_lines, explain
from app.results import plots as plot_defs
from app.service import jobs
from app.service.summary import headlines

router = APIRouter(include_in_schema=False)
MAX_LIST = 100  # the job list shows at most this many rows at once


def _summary(db, job_id: str, principal) -> dict:
    job = visible_job(db, job_id, principal)
    result = jobs.get_result(db, job_id) if job.status in ("succeeded", "failed") else None
    out: dict[str, Any] = {"status": job.status, "preset": job.preset, "headlines": [], "failure": None, "last_iterate_plots": []}
    if job.status == "succeeded":
        out["headlines"] = headlines(job.kind, result, job.params)
    elif job.status == "failed":
        out["failure"] = explain(job.error, result)
        # as the CLI prints it (it imports no kind)
        out["failure_lines"] = as_lines(out["failure"]) if out["failure"] is not None else []
        if result:
            out["last_iterate_plots"] = [{"name": p.name, "title": p.title,
                                          "png": f"/console/jobs/{job_id}/last-iterate/{p.name}.png"}
                                         for p in _plots(job.kind, result)]
    return out


def _plots(kind: str, result: dict) -> list:
    try:
        return plot_defs.plots_for(kind, result)
    except (KeyError, TypeError, ValueError):
        return []  # a last iterate without the blocks a plot's availability test reads


@router.get("/console/kinds/{kind}/schema")
def kind_schema(kind: str) -> dict:
    """The kind's parameter model as JSON schema (descriptions, bounds, enumerations, nullable fields):
    the New job form is built from it (app/web/static/form.js).  Public, as the presets are."""
    from app.kinds import KINDS

    if kind not in KINDS:
        raise HTTPException(status_code=404, detail=f"kind {kind} not found; known: {sorted(KINDS)}")
    return KINDS[kind].params_model.model_json_schema()


@router.get("/console/jobs/{job_id}/summary")
def job_summary(job_id: str, db: DatabaseDep, principal: PrincipalDep) -> dict:
    """The headlines of a succeeded job; the explanation and last-iterate plots of a failed one."""
    return _summary(db, job_id, principal)


@router.get("/console/headlines")
def list_headlines(db: DatabaseDep, principal: PrincipalDep,
                   ids: Annotated[str, Query(max_length=MAX_LIST * 33)]) -> dict:
    """The first headline (its text) of each succeeded job in ``ids`` (comma-separated) that the caller
    may see, for the job list's headline column; other jobs are left out."""
    out = {}
    for job_id in [i for i in ids.split(",") if i][:MAX_LIST]:
        try:
            job = visible_job(db, job_id, principal)
        except HTTPException:
            continue
        if job.status == "succeeded":
            lines = headlines(job.kind, jobs.get_result(db, job_id), job.params)
            out[job_id] = lines[0]["text"] if lines else ""
    return out


@router.get("/console/jobs/{job_id}/last-iterate/{name}.png")
async def last_iterate_plot(job_id: str, name: str, db: DatabaseDep, principal: PrincipalDep):
    """One plot of a failed job's stored last iterate (what the solver had when it stopped)."""
    job = await run_in_threadpool(visible_job, db, job_id, principal)
    if job.status != "failed":
        raise HTTPException(status_code=409, detail=f"job {job_id} is {job.status}; last-iterate plots are for "
                                                     "failed jobs (a succeeded one has /v1/jobs/{id}/plots)")
    result = await run_in_threadpool(jobs.get_result, db, job_id) or {}
    plot = next((p for p in _plots(job.kind, result) if p.name == name), None)
    if plot is None:
        raise HTTPException(status_code=404, detail=f"no last-iterate plot {name} for job {job_id}")
    title = f"{job_id[:8]}, last iterate"
    try:
        png = await run_in_threadpool(lambda: plot_defs.render(plot, result=result, params=job.params, title=title,
                                                               fmt="png"))
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise HTTPException(status_code=404,
                            detail=f"plot {name} cannot be drawn from this last iterate: {exc}") from exc
    return Response(png, media_type="image/png", headers={"Cache-Control": "private, max-age=3600"})
