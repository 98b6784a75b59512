"""/v1/studies: trade studies over any job kind (app/service/studies.py has the logic)."""
from __future__ import annotations

import csv
import io
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Body, HTTPException, Query, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel, Field, model_validator

from app.service import retention, studies, study_chart, submit
from app.api.access import Principal, PrincipalDep
from app.api.deps import DatabaseDep, PublisherDep, SettingsDep
from app.kinds import KINDS, PRESETS
from app.api.routes.results import forget
from app.service.params import deep_merge
from app.service.study_presets import STUDY_PRESETS
from app.results.study_plot import render as study_plot_render

router = APIRouter(prefix="/v1/studies", tags=["studies"])


class Sweep(BaseModel):
    """One swept parameter: a dotted path into `params` (or several set to the same value) and its values."""

    path: str | list[str] = Field(description="Dotted path(s) into params, e.g. `path.max_heat_rate_w_m2`",
                                  examples=["intercept_time_s"])
    values: list[Any] | None = Field(None, max_length=studies.MAX_POINTS,
                                     description="The values, in sweep order (any JSON the parameter takes); "
                                                 "or give start, stop and count instead",
                                     examples=[[7000.0, 8080.5, 9000.0]])
    start: float | None = Field(None, description="First value of an evenly spaced range (with stop and count)",
                                examples=[1.9e6])
    stop: float | None = Field(None, description="Last value of the range, included", examples=[2.0e5])
    count: int | None = Field(None, ge=2, le=studies.MAX_POINTS,
                              description="Number of values from start to stop inclusive", examples=[10])

    @model_validator(mode="after")
    def _values_or_range(self) -> "Sweep":
        if (self.values is None) == (self.count is None or self.start is None or self.stop is None):
            raise ValueError("give either values or start, stop and count")
        if self.values is not None and not self.values:
            raise ValueError("values must not be empty")
        paths = [self.path] if isinstance(self.path, str) else self.path
        if not paths or any(not p or len(p) > 200 for p in paths):
            raise ValueError("path must name at least one parameter")
        return self


class StudySubmission(BaseModel):
    """A trade study: a base job (kind, preset, params) and one or two swept parameters; each point is an
    ordinary job.  Name a `study_preset` and every other field is optional (what is given overrides it)."""

    kind: str | None = Field(None, description="Job kind of every point (taken from the study preset when one "
                                               "is named)", examples=["reentry"])
    study_preset: str | None = Field(None, description="A named study (GET /v1/studies/presets), e.g. "
                                                       "`crossrange-vs-heating`", examples=["crossrange-vs-heating"])
    preset: str | None = Field(None, description="The base job's preset (GET /v1/presets)",
                               examples=["betts-max-crossrange"])
    params: dict[str, Any] | None = Field(None, description="Base job parameters, deep-merged onto the preset "
                                                            "(and onto the study preset's own params)",
                                          examples=[{"grid": {"intervals": 50}}])
    sweeps: list[Sweep] | None = Field(None, min_length=1, max_length=2,
                                       description="One sweep, or two (their grid: every pair of values); at most "
                                                   f"{studies.MAX_POINTS} points in all")
    mode: Literal["independent", "continuation"] | None = Field(
        None, description="`independent`: every point is queued at once and starts cold (a failed point is "
                          "retried once from a solved neighbour); `continuation`: points run one at a time in "
                          "sweep order, each warm-started from the nearest solved point (the kind's `from_job`; "
                          "for kinds without one, midcourse, it is the same as independent one by one)",
        examples=["continuation"])
    label: str | None = Field(None, max_length=200, description="A name of your own for the study")


class StudyOut(BaseModel):
    id: str
    kind: str
    label: str | None
    preset: str | None
    mode: str
    status: str = Field(description="running, finished (every point has a final status) or cancelled")
    progress: float = Field(description="Share of points finished")
    points: int
    points_by_status: dict[str, int]
    sweeps: list[dict[str, Any]]
    base_params: dict[str, Any]
    created_at: str | None
    finished_at: str | None


def _visible(db, study_id: str, principal: Principal):
    study = studies.get_study(db, study_id)
    if study is None or not principal.may_see(study):  # the jobs' rule: another owner's study is a 404
        raise HTTPException(status_code=404, detail=f"study {study_id} not found")
    return study


def _resolve(body: StudySubmission) -> dict:
    merged: dict = {}
    if body.study_preset:
        if body.study_preset not in STUDY_PRESETS:
            raise HTTPException(status_code=422, detail=f"study_preset must be one of {sorted(STUDY_PRESETS)}")
        merged = dict(STUDY_PRESETS[body.study_preset])
    given = body.model_dump(exclude_unset=True, exclude_none=True)
    given.pop("study_preset", None)
    if "params" in given:
        given["params"] = deep_merge(merged.get("params", {}), given["params"])
    merged.update(given)
    for name in ("kind", "sweeps", "mode"):
        if merged.get(name) is None:
            raise HTTPException(status_code=422, detail=f"{name} is required (or name a study_preset)")
    if merged["kind"] not in KINDS:
        raise HTTPException(status_code=422, detail=f"kind must be one of {sorted(KINDS)}")
    preset = merged.get("preset")
    if preset is not None and (preset not in PRESETS or PRESETS[preset].kind != merged["kind"]):
        raise HTTPException(status_code=422, detail=f"preset {preset} is not a {merged['kind']} preset")
    merged["sweeps"] = [Sweep.model_validate(s).model_dump(exclude_none=True) for s in merged["sweeps"]]
    return merged


@router.get("/presets")
def list_study_presets() -> dict[str, dict]:
    return STUDY_PRESETS


@router.post("", status_code=202, response_model=StudyOut, operation_id="submit_study",
             responses={422: {"description": "Invalid base job or sweep (the message names the point and field)"}})
def submit_study(body: Annotated[StudySubmission, Body(openapi_examples={
        **{name: {"summary": f"The named study {name}", "description": p["description"],
                  "value": {"study_preset": name}} for name, p in STUDY_PRESETS.items()},
        "own": {"summary": "A sweep of your own: reentry crossrange against the final speed",
                "value": {"kind": "reentry", "preset": "betts-max-crossrange", "params": {"grid": {"intervals": 30}},
                          "sweeps": [{"path": "terminal.speed_mps", "values": [762.0, 1000.0, 1200.0]}],
                          "mode": "continuation", "label": "crossrange vs final speed"}}})],
        response: Response, db: DatabaseDep, settings: SettingsDep, publisher: PublisherDep, principal: PrincipalDep):
    spec_body = _resolve(body)
    # app.service.submit admits it; its refusals are 422s and 429s (app.api.errors)
    study = submit.submit_study(db, settings, publisher, kind=spec_body["kind"], preset=spec_body.get("preset"),
                                overrides=spec_body.get("params"), sweeps=spec_body["sweeps"],
                                mode=spec_body["mode"], label=spec_body.get("label"), owner=principal.owner)
    response.headers["Location"] = f"/v1/studies/{study.id}"
    return studies.summary(db, study)


@router.get("", response_model=list[StudyOut])
def list_studies(db: DatabaseDep, principal: PrincipalDep,
                 limit: Annotated[int, Query(ge=1, le=200)] = 50, offset: Annotated[int, Query(ge=0, le=2**62)] = 0):
    return [studies.summary(db, s) for s in studies.list_studies(db, owner=principal.owner_filter,
                                                                  limit=limit, offset=offset)]


@router.get("/{study_id}", response_model=StudyOut, responses={404: {"description": "Unknown study"}})
def get_study(study_id: str, db: DatabaseDep, publisher: PublisherDep, principal: PrincipalDep):
    study = _visible(db, study_id, principal)
    if study.status == "running":
        # The worker moves a study on when a point finishes; a point that ended elsewhere (cancelled,
        # given up by the reaper) is caught here as well as by the recovery loop.
        publisher.send(studies.advance(db, study_id))
        study = studies.get_study(db, study_id)
    return studies.summary(db, study)


@router.get("/{study_id}/result", responses={404: {"description": "Unknown study"}})
def get_study_result(study_id: str, db: DatabaseDep, principal: PrincipalDep,
                     format: Annotated[Literal["json", "csv"], Query()] = "json"):
    """The trade table: one row per point (swept values, status, key numbers, job id)."""
    study = _visible(db, study_id, principal)
    rows = studies.trade_table(db, study)
    if format == "csv":
        columns: list[str] = []
        for row in rows:
            columns += [c for c in row if c not in columns]
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        return PlainTextResponse(buf.getvalue(), media_type="text/csv")
    return {"study": studies.summary(db, study), "rows": rows}


@router.post("/{study_id}/cancel", status_code=202, response_model=StudyOut,
             responses={404: {"description": "Unknown study"}})
def cancel_study(study_id: str, db: DatabaseDep, principal: PrincipalDep):
    _visible(db, study_id, principal)
    studies.request_cancel(db, study_id)
    return studies.summary(db, _visible(db, study_id, principal))


@router.delete("/{study_id}", status_code=204, response_class=Response,
               responses={204: {"description": "Deleted with every point job (running points are cancelled "
                                               "first); 404 from now on"},
                          404: {"description": "Unknown study (or another owner's)"}})
def delete_study(study_id: str, db: DatabaseDep, principal: PrincipalDep) -> Response:
    """Delete a study and every point job with its result, by its owner or an admin."""
    _visible(db, study_id, principal)
    deleted = retention.delete_study(db, study_id)
    if deleted is None:
        raise HTTPException(status_code=404, detail=f"study {study_id} not found")
    forget(deleted)
    return Response(status_code=204)


@router.get("/{study_id}/plot.{fmt}", responses={404: {"description": "Unknown study"},
                                                  200: {"content": {"image/png": {}, "image/svg+xml": {}}}})
async def study_plot(study_id: str, fmt: Literal["png", "svg"], db: DatabaseDep, principal: PrincipalDep):
    """The trade curve: each output that varies (the kind's objective, named results and final time, with
    units) against the (first) swept value; failed points marked on the axis; counts and booleans stay in
    the table (app.service.study_chart)."""
    study = await run_in_threadpool(_visible, db, study_id, principal)
    chart = await run_in_threadpool(study_chart.trade_chart, db, study)
    body = await run_in_threadpool(study_plot_render, chart, fmt)
    return Response(body, media_type="image/png" if fmt == "png" else "image/svg+xml")
