"""The job routes write the job document themselves (app.service.jobs.job_json): it must be the document FastAPI
wrote through ``response_model=JobOut`` (pydantic's validation and JSON), field for field and character for
character in every string, for every form a stored job takes (SQLite's naive times, PostgreSQL's aware ones in
any session time zone, whole seconds, an error with and without details)."""
from __future__ import annotations

import json
from datetime import datetime, timedelta, timezone

import pytest

from app.service import jobs
from app.service.job_document import job_json, job_to_dict
from app.runtime.models import Job
from app.api.schemas import JobList, JobOut

BERLIN = timezone(timedelta(hours=1))


def _job(**kw) -> Job:
    base = dict(id="0123456789abcdef0123456789abcdef", kind="reentry", label=None, preset="betts-max-crossrange",
                status="queued", progress=0.0, message="queued", params={"grid": {"intervals": 100, "tol": 1e-5},
                                                                        "objective": "max_crossrange"},
                error=None, attempts=1, created_at=datetime(2025, 3, 1, 12, 0, 0, 123456, tzinfo=timezone.utc),
                started_at=None, finished_at=None)
    return Job(**{**base, **kw})


CASES = {
    "queued, aware UTC": _job(),
    "naive (SQLite), whole second": _job(created_at=datetime(2025, 3, 1, 12, 0, 0)),
    "aware, another session time zone": _job(created_at=datetime(2025, 3, 1, 13, 0, 0, 5, tzinfo=BERLIN)),
    "failed with details": _job(status="failed", progress=0.42, started_at=datetime(2025, 3, 1, 12, 0, 1),
                                finished_at=datetime(2025, 3, 1, 12, 0, 9, 999999, tzinfo=timezone.utc),
                                error={"code": "infeasible", "message": "IPOPT: Infeasible_Problem_Detected",
                                       "details": {"iterations": 31, "max_constraint_violation": 0.5}},
                                label="ünïcode \u2603", attempts=2),
    "cancelled without details": _job(status="cancelled", error={"code": "cancelled", "message": "by request"}),
}


@pytest.mark.parametrize("name", CASES)
def test_job_json_is_what_response_model_wrote(name):
    job = CASES[name]
    fastapi_wrote = json.loads(JobOut.model_validate(job_to_dict(job)).model_dump_json())
    assert json.loads(job_json(job)) == fastapi_wrote
    assert list(json.loads(job_json(job))) == list(JobOut.model_fields)  # same fields, same order


def check_listing(db, owner: str | None = None) -> None:
    """``list_jobs_json`` (one query, params as stored text) against ``JobList`` over ``list_jobs`` (ORM
    objects, what the route returned before), with filters, paging and past the end, over ``owner``'s jobs
    (a database with no other jobs when None)."""
    params = {"grid": {"intervals": 100, "tol": 1e-5}, "label": "\u00fcn\u00efcode \u2603 \"quoted\"",
              "list": [1, 2.5, None, True], "big": 12345678901234567890}
    for i in range(7):
        job, _ = jobs.create_job(db, kind="reentry" if i % 2 else "intercept", params={**params, "i": i},
                                 label=',"params":null,' if i == 3 else f"job {i}", preset=None,
                                 owner=owner)
        if i == 2:
            jobs.claim(db, job.id, 1, worker="w", max_attempts=3, stale_after_s=60)
            jobs.finish(db, job.id, 1, status="failed", result=None, message="failed",
                        error={"code": "infeasible", "message": "IPOPT: Infeasible_Problem_Detected"})
    for query in ({}, {"kind": "reentry"}, {"status": "failed"}, {"limit": 2, "offset": 1},
                  {"kind": "intercept", "limit": 3, "offset": 3}, {"offset": 50}):
        q = {"kind": None, "status": None, "limit": 20, "offset": 0, "owner": owner, **query}
        items, total = jobs.list_jobs(db, **q)
        before = JobList.model_validate({"items": [job_to_dict(j) for j in items], "total": total})
        assert json.loads(jobs.list_jobs_json(db, **q)) == json.loads(before.model_dump_json()), query
    page = json.loads(jobs.list_jobs_json(db, kind=None, status=None, limit=20, offset=0, owner=owner))
    assert page["total"] == 7 and [j["params"]["i"] for j in page["items"]] == list(range(6, -1, -1))
    assert page["items"][3]["label"] == ',"params":null,' and page["items"][3]["params"]["big"] == 12345678901234567890
    past = jobs.list_jobs_json(db, kind=None, status=None, limit=5, offset=50, owner=owner)
    assert json.loads(past) == {"items": [], "total": 7}


def test_list_jobs_json_is_what_response_model_wrote_sqlite(sqlite_db):
    check_listing(sqlite_db)


def test_a_non_finite_number_is_refused_not_written_as_invalid_json():
    with pytest.raises(ValueError):
        job_json(_job(progress=float("nan")))
