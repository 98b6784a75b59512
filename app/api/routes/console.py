"""The web console at ``/``: server-rendered pages (Jinja2) over the public API, no build step.

The pages are shells rendered with what is public (kinds, presets); the job
data is fetched by a little plain JavaScript (``app/web/static/console.js``)
from the same ``/v1`` routes any client uses, with the API key the console
asks for once (kept in the browser's localStorage).  So the console shows
exactly what that key may see, and nothing here bypasses ``app/api/access.py``.
Nothing is loaded from the internet.
"""
from __future__ import annotations

import io
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import HTMLResponse, Response
from fastapi.templating import Jinja2Templates

from app.service import jobs
from app.api.access import PrincipalDep, visible_job
from app.api.deps import DatabaseDep
from app.kinds import KINDS, PRESETS
from app.kinds.base import CompareSeries
from app.service.summary import WARM_START_FIELD

WEB = Path(__file__).resolve().parents[2] / "web"
templates = Jinja2Templates(directory=str(WEB / "templates"))
router = APIRouter(include_in_schema=False)


def _page(request: Request, name: str, **context) -> HTMLResponse:
    # what the pages' scripts know of each kind, from its KindSpec: "json" (the params are a document, edited
    # as JSON: KindSpec.json_editor), "extras" (the job page's sections its results fill), the warm-start field
    kinds = {k: {"summary": s.summary, "presets": [p.name for p in s.presets], "json": s.json_editor,
                 "extras": list(s.console_extras)}
             for k, s in KINDS.items()}
    return templates.TemplateResponse(request, name, {"kinds": kinds, "warm_fields": dict(WARM_START_FIELD),
                                                      **context})


@router.get("/", response_class=HTMLResponse)
def job_list(request: Request):
    return _page(request, "jobs.html", title="Jobs")


@router.get("/new", response_class=HTMLResponse)
def new_job(request: Request):
    presets = {name: {"kind": p.kind, "description": p.description} for name, p in PRESETS.items()}
    return _page(request, "new.html", title="New job", presets=presets)


@router.get("/jobs/{job_id}", response_class=HTMLResponse)
def job_page(request: Request, job_id: str):
    return _page(request, "job.html", title=f"Job {job_id[:8]}", job_id=job_id)


@router.get("/studies", response_class=HTMLResponse)
def studies_page(request: Request):
    from app.service.study_presets import STUDY_PRESETS

    return _page(request, "studies.html", title="Studies",
                 study_presets={n: {"kind": p["kind"], "description": p["description"]} for n, p in STUDY_PRESETS.items()})


@router.get("/studies/{study_id}", response_class=HTMLResponse)
def study_page(request: Request, study_id: str):
    return _page(request, "study.html", title=f"Study {study_id[:8]}", study_id=study_id)


@router.get("/compare", response_class=HTMLResponse)
def compare_page(request: Request, ids: str = ""):
    return _page(request, "compare.html", title="Compare", ids=ids)


MAX_COMPARE = 8


@router.get("/console/compare.png")
async def compare_png(db: DatabaseDep, principal: PrincipalDep,
                      ids: Annotated[str, Query(max_length=MAX_COMPARE * 33)]):
    """Two or more succeeded jobs of one kind overlaid on one plot (PNG)."""
    job_ids = [i for i in ids.split(",") if i][:MAX_COMPARE]
    if len(job_ids) < 2:
        raise HTTPException(status_code=422, detail="compare needs at least two job ids")
    loaded = []
    for job_id in job_ids:
        job = await run_in_threadpool(visible_job, db, job_id, principal)
        if job.status != "succeeded":
            raise HTTPException(status_code=409, detail=f"job {job_id} is {job.status}; compare needs succeeded jobs")
        loaded.append((job, await run_in_threadpool(jobs.get_result, db, job_id)))
    if len({job.kind for job, _ in loaded}) != 1:
        raise HTTPException(status_code=422, detail="compare needs jobs of one kind")
    png = await run_in_threadpool(render_compare, loaded)
    return Response(png, media_type="image/png", headers={"Cache-Control": "private, max-age=3600"})


def _series(kind: str, result: dict) -> CompareSeries:
    """The curve that best shows a job of this kind (``KindSpec.compare``); a 422 for a kind without one or a
    result that lacks it."""
    spec = KINDS.get(kind)
    if spec is None or spec.compare is None:
        raise HTTPException(status_code=422, detail=f"no comparison plot for kind {kind}")
    try:
        return spec.compare(result)
    except ValueError as exc:
        raise HTTPException(status_code=422, detail=str(exc)) from None


def render_compare(loaded) -> bytes:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5), dpi=100)
    ax = fig.add_subplot()
    kind = loaded[0][0].kind
    for job, result in loaded:
        series = _series(kind, result)
        ax.plot(series.x, series.y, series.style, ms=3, lw=1.5, label=job.label or job.id[:8])
    ax.set_xlabel(series.x_label)
    ax.set_ylabel(series.y_label)
    ax.set_title(f"{kind}: {len(loaded)} jobs compared")
    ax.grid(True, alpha=0.3)
    ax.legend()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


@router.get("/console/jobs/{job_id}/numbers")
def job_numbers(job_id: str, db: DatabaseDep, principal: PrincipalDep) -> dict:
    """The key numbers the job page shows (the same as the CLI's): empty until the job succeeded."""
    from app.service.summary import key_numbers

    job = visible_job(db, job_id, principal)
    return key_numbers(job.kind, jobs.get_result(db, job_id)) if job.status == "succeeded" else {}


def mount_static(app) -> None:
    from fastapi.staticfiles import StaticFiles

    app.mount("/console/static", StaticFiles(directory=str(WEB / "static")), name="console-static")
