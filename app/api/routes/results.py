"""/v1/jobs/{id}/plots, /report.html, /result.csv: a succeeded job's result as pictures and files.

A succeeded result never changes, so every rendering is cached in-process (an LRU keyed by job,
name and format: a plot is rendered once per API process) and served with a strong ETag and a
long private Cache-Control; ``If-None-Match`` gets a 304.  Every route loads the job through
``visible_job`` (owner isolation).
"""
from __future__ import annotations

from collections import OrderedDict
from threading import Lock
from typing import Annotated, Literal

from fastapi import APIRouter, Header, HTTPException, Query
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import HTMLResponse, PlainTextResponse, Response

from app.service import job_document, jobs
from app.api.access import PrincipalDep, visible_job
from app.api.deps import DatabaseDep
from app.results import plots as plot_defs
from app.kinds import KINDS
from app.api.schemas import ErrorBody
from app.api.security_headers import REPORT_CSP
from app.results.report import render_report
from app.results.tables import tables_for, to_csv
from app.service.summary import headlines, key_numbers

router = APIRouter(prefix="/v1/jobs", tags=["results"])
CACHE_CONTROL = "private, max-age=86400"
_CACHE: OrderedDict[tuple, bytes] = OrderedDict()
_CACHE_LOCK = Lock()
_CACHE_ENTRIES = 256
MEDIA = {"png": "image/png", "svg": "image/svg+xml"}


def _cached(key: tuple, make) -> bytes:
    with _CACHE_LOCK:
        if key in _CACHE:
            _CACHE.move_to_end(key)
            return _CACHE[key]
    value = make()
    with _CACHE_LOCK:
        _CACHE[key] = value
        while len(_CACHE) > _CACHE_ENTRIES:
            _CACHE.popitem(last=False)
    return value


def forget(job_ids) -> None:
    """Drop a deleted job's renderings from this process's cache (another API process's copies can no
    longer be reached: every route loads the job first, a 404 once it is deleted, and they age out)."""
    gone = set(job_ids)
    with _CACHE_LOCK:
        for key in [k for k in _CACHE if k[0] in gone]:
            del _CACHE[key]


def _succeeded(db, job_id: str, principal):
    job = visible_job(db, job_id, principal)
    if job.status != "succeeded":
        raise HTTPException(status_code=409, detail=f"job {job_id} is {job.status}; plots, reports and files "
                                                     "exist once it has succeeded")
    return job, jobs.get_result(db, job_id)


def _oem(kind: str, result: dict):
    """The kind's OEM export (``KindSpec.oem``) if this result has a trajectory to write, else None."""
    spec = KINDS.get(kind)
    oem = spec.oem if spec is not None else None
    return oem if oem is not None and oem.available(result) else None


def _title(job) -> str:
    return f"{job.kind} {job.label or job.id[:8]}"


def _etag(job_id: str, *parts: str) -> str:
    return '"' + "-".join((job_id, *parts)) + '"'


def _not_modified(etag: str, if_none_match: str | None) -> Response | None:
    if if_none_match and etag in [t.strip() for t in if_none_match.split(",")]:
        return Response(status_code=304, headers={"ETag": etag, "Cache-Control": CACHE_CONTROL})
    return None


@router.get("/{job_id}/plots", operation_id="list_plots",
            responses={404: {"model": ErrorBody, "description": "Unknown job"}, 409: {"model": ErrorBody, "description": "Not succeeded (yet)"}})
def list_plots(job_id: str, db: DatabaseDep, principal: PrincipalDep) -> dict:
    """The job's plots (PNG and SVG URLs), CSV tables and report."""
    job, result = _succeeded(db, job_id, principal)
    base = f"/v1/jobs/{job_id}"
    return {
        "plots": [{"name": p.name, "title": p.title, "png": f"{base}/plots/{p.name}.png",
                   "svg": f"{base}/plots/{p.name}.svg"} for p in plot_defs.plots_for(job.kind, result)],
        "tables": [{"name": name, "url": f"{base}/result.csv?table={name}", "columns": list(cols)}
                   for name, cols in tables_for(job.kind, result).items()],
        "report": f"{base}/report.html",
        "oem": f"{base}/result.oem" if _oem(job.kind, result) is not None else None,
    }


@router.get("/{job_id}/plots/{name}.{fmt}", operation_id="get_plot",
            responses={200: {"content": {"image/png": {}, "image/svg+xml": {}}},
                       304: {"description": "Not modified (If-None-Match)"},
                       404: {"model": ErrorBody, "description": "Unknown job or plot name"}, 409: {"model": ErrorBody, "description": "Not succeeded"}})
async def get_plot(job_id: str, name: str, fmt: Literal["png", "svg"], db: DatabaseDep, principal: PrincipalDep,
                   if_none_match: Annotated[str | None, Header()] = None):
    job, result = await run_in_threadpool(_succeeded, db, job_id, principal)
    etag = _etag(job_id, name, fmt)
    if (hit := _not_modified(etag, if_none_match)) is not None:
        return hit
    plot = next((p for p in plot_defs.plots_for(job.kind, result) if p.name == name), None)
    if plot is None:
        raise HTTPException(status_code=404, detail=f"job {job_id} has no plot {name}")
    body = await run_in_threadpool(_cached, (job_id, name, fmt), lambda: plot_defs.render(
        plot, result=result, params=job.params, title=_title(job), fmt=fmt))
    return Response(body, media_type=MEDIA[fmt], headers={"ETag": etag, "Cache-Control": CACHE_CONTROL})


@router.get("/{job_id}/report.html", operation_id="get_report", response_class=HTMLResponse,
            responses={404: {"model": ErrorBody, "description": "Unknown job"}, 409: {"model": ErrorBody, "description": "Not succeeded"}})
async def get_report(job_id: str, db: DatabaseDep, principal: PrincipalDep,
                     if_none_match: Annotated[str | None, Header()] = None):
    """One self-contained HTML file (plots inlined as SVG, no external assets)."""
    job, result = await run_in_threadpool(_succeeded, db, job_id, principal)
    etag = _etag(job_id, "report")
    if (hit := _not_modified(etag, if_none_match)) is not None:
        return hit

    def make() -> bytes:
        svgs = [(p.title, _cached((job_id, p.name, "svg"), lambda p=p: plot_defs.render(
            p, result=result, params=job.params, title=_title(job), fmt="svg")).decode())
            for p in plot_defs.plots_for(job.kind, result)]
        return render_report(job=job_document.job_to_dict(job), result=result, key_numbers=key_numbers(job.kind, result),
                             headlines=headlines(job.kind, result, job.params),
                             svgs=svgs).encode()

    body = await run_in_threadpool(_cached, (job_id, "report", "html"), make)
    return HTMLResponse(body, headers={"ETag": etag, "Cache-Control": CACHE_CONTROL, "Content-Security-Policy": REPORT_CSP})


@router.get("/{job_id}/result.csv", operation_id="get_result_csv", response_class=PlainTextResponse,
            responses={200: {"content": {"text/csv": {}}}, 404: {"model": ErrorBody, "description": "Unknown job or table"},
                       409: {"model": ErrorBody, "description": "Not succeeded"}})
def get_result_csv(job_id: str, db: DatabaseDep, principal: PrincipalDep,
                   table: Annotated[str | None, Query(max_length=64, description="A table name from GET .../plots")]
                   = None):
    """One table of the result as CSV, with unit-bearing column headers (`t_s,altitude_m,...`)."""
    job, result = _succeeded(db, job_id, principal)
    tables = tables_for(job.kind, result)
    if table is None:  # checked after the job, so another owner's job is a 404 either way
        raise HTTPException(status_code=422, detail=f"table is required; this job has {sorted(tables)}")
    if table not in tables:
        raise HTTPException(status_code=404, detail=f"job {job_id} has no table {table[:64]}; "
                                                     f"known: {sorted(tables)}")
    return PlainTextResponse(to_csv(tables[table]), media_type="text/csv",
                             headers={"ETag": _etag(job_id, "csv", table), "Cache-Control": CACHE_CONTROL,
                                      "Content-Disposition": f'attachment; filename="{job_id}-{table}.csv"'})


@router.get("/{job_id}/result.oem", operation_id="get_result_oem", response_class=PlainTextResponse,
            responses={200: {"content": {"application/ccsds-oem": {}}},
                       304: {"description": "Not modified (If-None-Match)"},
                       404: {"model": ErrorBody, "description": "Unknown job, a job without a trajectory to write, "
                                                                "or no such front point"},
                       409: {"model": ErrorBody, "description": "Not succeeded"}})
async def get_result_oem(job_id: str, db: DatabaseDep, principal: PrincipalDep,
                         point: Annotated[int | None, Query(ge=0, le=100_000, description=(
                             "midcourse: the Pareto-front point whose corrected flight is written "
                             "(default: the point of least delta-v)"))] = None,
                         trajectory: Annotated[Literal["corrected", "nominal"], Query(description=(
                             "midcourse: `corrected` (the chosen point's flight, one segment per coast) or "
                             "`nominal` (the error-free transfer)"))] = "corrected",
                         if_none_match: Annotated[str | None, Header()] = None):
    """A trajectory as a CCSDS OEM 2.0 (KVN): centre EARTH, REF_FRAME EME2000, TDB, km and km/s; t0
    written as J2000 because the parameters have no calendar epoch.  intercept: the finite-thrust
    interceptor (Hill states converted with the target's exact circular orbit).  midcourse: the
    corrected flight of a front point or the nominal transfer, re-flown with the solver's J2
    propagator and Lambert impulses, in the Earth-centred inertial frame of the launch frame (z the
    spin axis, x the launch meridian at t0; the COMMENT lines say so)."""
    job, result = await run_in_threadpool(_succeeded, db, job_id, principal)
    oem = _oem(job.kind, result)
    if oem is None:
        raise HTTPException(status_code=404, detail=f"job {job_id} has no trajectory to write")
    try:
        view, make = oem.prepare(result, job.params, object_name=job.label or job.id, point=point,
                                 trajectory=trajectory)
    except LookupError as exc:
        raise HTTPException(status_code=404, detail=f"job {job_id} has {exc.args[0]}") from None
    etag = _etag(job_id, "oem", *view)
    if (hit := _not_modified(etag, if_none_match)) is not None:
        return hit
    body = await run_in_threadpool(_cached, (job_id, "result", "oem", *view), lambda: make().encode())
    name = "-".join((job_id, *view))
    return Response(body, media_type="application/ccsds-oem",
                    headers={"ETag": etag, "Cache-Control": CACHE_CONTROL,
                             "Content-Disposition": f'attachment; filename="{name}.oem"'})


@router.get("/{job_id}/params", operation_id="get_resubmit_body",
            responses={404: {"model": ErrorBody, "description": "Unknown job"}})
def get_resubmit_body(job_id: str, db: DatabaseDep, principal: PrincipalDep) -> dict:
    """The job's resolved parameters as a body `POST /v1/jobs` accepts unchanged (re-runs the job).

    Any status: a failed or cancelled job is the one a user most wants to run again.
    """
    job = visible_job(db, job_id, principal)
    return {"kind": job.kind, "params": job.params, "label": job.label}
