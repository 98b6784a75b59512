"""Issue 30: a study advances only from the attempt whose result was stored.

A point's first attempt goes stale mid-run (its host cut off), the reaper hands the job to a second
attempt, which runs, stores its result and moves the study on; then the first attempt finishes.  Its
write is refused by the attempt token (the compare-and-set of ``jobs.finish``), and so is everything
after it: it moves the study on no further, publishes nothing, and reports itself refused.
"""
from __future__ import annotations

import logging
from datetime import timedelta
from types import SimpleNamespace

from pydantic import BaseModel, ConfigDict
from sqlalchemy import update

from app.runtime.models import Job, utcnow
from app.runtime.settings import Settings
from app.service import jobs, studies
from worker import tasks

BASE = {"grid": {"intervals": 20}, "path": {"max_heat_rate_w_m2": None}, "initial_guess": {"from_job": None}}


class AnyParams(BaseModel):
    model_config = ConfigDict(extra="allow")


def test_a_stale_attempt_finishing_after_its_takeover_moves_the_study_on_not_at_all(sqlite_db, monkeypatch, caplog):
    db = sqlite_db
    settings = Settings(database_url=db.url, heartbeat_interval_s=3600, stale_after_s=60, max_attempts=3)
    published: list[tuple[int | None, int]] = []
    monkeypatch.setattr(tasks, "publish_or_defer",
                        lambda _db, _app, _settings, job: published.append((job.study_index, job.attempts)))
    sweeps = [{"path": "path.max_heat_rate_w_m2", "values": [3.0, 2.0, 1.0]}]
    study, created = studies.create_study(db, kind="reentry", preset=None, label="stale", base_params=BASE,
                                          sweeps=sweeps, mode="continuation",
                                          points=studies.expand(BASE, sweeps), owner=None, queue="trajlab.jobs")
    point0 = created[0].id
    outcomes: dict[int, str | None] = {}

    def run(_params, ctx):
        if ctx.attempt == 1:
            # Attempt 1's host is cut off: its heartbeat goes stale, the reaper re-queues the job, and
            # attempt 2 runs it to the end (stored, study moved on) before attempt 1 finishes.
            with db.write() as s:
                s.execute(update(Job).where(Job.id == point0).values(heartbeat_at=utcnow() - timedelta(seconds=600)))
            requeued = jobs.reap_stale(db, stale_after_s=settings.stale_after_s, max_attempts=settings.max_attempts)
            assert [j.id for j in requeued] == [point0]
            outcomes[2] = tasks.execute_job(db, settings, point0, 2, worker="host-b")
        from app.kinds.base import RunOutcome

        return RunOutcome("succeeded", result={"objective": {"value": float(ctx.attempt)}})

    monkeypatch.setitem(tasks.KINDS, "reentry", SimpleNamespace(params_model=AnyParams, run=run, time_limit_s=600))
    with caplog.at_level(logging.INFO, logger="trajlab.worker"):
        outcomes[1] = tasks.execute_job(db, settings, point0, 1, worker="host-a")

    assert outcomes == {2: "succeeded", 1: tasks.REFUSED}
    points = studies.point_jobs(db, study.id)
    assert sorted(j.study_index for j in points) == [0, 1]  # exactly one next point
    assert published == [(1, 1)]  # published once, by attempt 2
    job0 = jobs.get_job(db, point0)
    assert (job0.status, job0.attempts, jobs.get_result(db, point0)) == ("succeeded", 2, {"objective": {"value": 2.0}})
    # the backstop sees nothing more to do while point 1 is queued
    assert studies.advance(db, study.id) == []
    refused = [r.getMessage() for r in caplog.records if "refused" in r.getMessage()]
    assert len(refused) == 1 and f"job {point0} attempt 1 refused" in refused[0]
