"""Admission without HTTP (app.service.submit): the refusals are typed exceptions, a refused study stores
nothing, and a submitted job and a study's point are queued rows of the same shape (SQLite, and a broker
that cannot be reached: accepted work stays queued, kept by the publisher and marked unpublished)."""
from __future__ import annotations

import threading
import time

import pytest
from sqlalchemy import func, select

from app.runtime.models import Job, Study
from app.runtime.settings import Settings
from app.service import jobs, studies, submit
from app.service.broker import create_publisher
from app.service.publisher import Publisher
from app.service.params import InvalidParams

INTERCEPT = {"methods": ["impulsive"]}


@pytest.fixture
def setup(sqlite_db):
    settings = Settings(database_url="sqlite://", broker_url="redis://127.0.0.1:1/0", job_memory_mb=400)
    return sqlite_db, settings, Publisher(sqlite_db, create_publisher(settings), settings)


def _count(db, table) -> int:
    with db.read() as s:
        return s.scalar(select(func.count()).select_from(table))


def test_a_job_and_a_study_point_are_the_same_queued_row(setup):
    db, settings, publisher = setup
    job = submit.submit_job(db, settings, publisher, kind="intercept", preset="long-range-intercept",
                            overrides=INTERCEPT, label="one", owner="ann")
    study = submit.submit_study(db, settings, publisher, kind="intercept", preset="long-range-intercept",
                                overrides=INTERCEPT, sweeps=[{"path": "intercept_time_s", "values": [7000.0]}],
                                mode="independent", label="s", owner="ann")
    # nothing listens on port 1: the publisher's thread finds the broker down and marks both unpublished
    deadline = time.monotonic() + 30
    while any(jobs.get_job(db, j).published_at is not None for j in (job.id, studies.point_jobs(db, study.id)[0].id)):
        assert time.monotonic() < deadline, "the publisher did not mark the jobs unpublished"
        time.sleep(0.05)
    assert publisher.pending() == 2  # kept for the broker's return
    job = jobs.get_job(db, job.id)
    (point,) = studies.point_jobs(db, study.id)
    for row in (job, point):
        assert (row.status, row.attempts, row.progress, row.owner, row.kind) == ("queued", 1, 0.0, "ann", "intercept")
        assert row.published_at is None and "waiting for the broker" in row.message  # deferred, not failed
        assert row.stored_bytes > 0 and row.params["methods"] == ["impulsive"]
    assert point.study_id == study.id and point.study_index == 0 and job.study_id is None


def test_refusals_are_typed_and_a_refused_study_stores_nothing(setup):
    db, settings, publisher = setup
    with pytest.raises(InvalidParams) as bad:
        submit.submit_job(db, settings, publisher, kind="reentry", preset="betts-max-crossrange", label=None,
                          owner=None, overrides={"initial_guess": {"from_job": "0" * 32}})
    assert bad.value.errors[0]["loc"] == ("params", "initial_guess", "from_job")
    assert "does not exist" in bad.value.errors[0]["msg"]
    with pytest.raises(submit.Refused, match=r"point 1 .*TRAJLAB_JOB_MEMORY_MB"):
        submit.submit_study(db, settings, publisher, kind="robust_reentry", preset="robust-max-crossrange",
                            overrides=None, sweeps=[{"path": "grid.intervals", "values": [100, 1000]}],
                            mode="independent", label=None, owner=None)
    with pytest.raises(submit.Refused, match="sweeps: nope"):
        submit.submit_study(db, settings, publisher, kind="intercept", preset="long-range-intercept",
                            overrides=INTERCEPT, sweeps=[{"path": "nope", "values": [1]}], mode="independent",
                            label=None, owner=None)
    assert _count(db, Job) == 0 and _count(db, Study) == 0


def test_sending_nothing_starts_no_publisher_thread(setup):
    # GET /v1/studies/{id} hands over what the study's advance created, most often nothing: no thread for that
    # (one started before and then idled 30 s).  Other tests' publisher threads may end meanwhile, never start.
    _, _, publisher = setup

    def publishers() -> int:
        return sum(t.name == "trajlab-publisher" for t in threading.enumerate())

    before = publishers()
    publisher.send([])
    assert publishers() <= before and publisher.pending() == 0
