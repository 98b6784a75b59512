"""The job life cycle rules of app.service.jobs on the embedded SQLite database."""
from __future__ import annotations

import threading
from datetime import timedelta

import pytest
from sqlalchemy import update

from app.service import jobs
from app.runtime.models import Job, utcnow


def _new(db, **kw):
    job, created = jobs.create_job(db, kind="intercept", params={"a": 1}, label=None, preset=None, **kw)
    assert created
    return job


def test_claim_runs_only_current_token(sqlite_db):
    job = _new(sqlite_db)
    assert jobs.claim(sqlite_db, job.id, attempt=2, worker="w", max_attempts=3, stale_after_s=60) is None  # stale/future token
    c = jobs.claim(sqlite_db, job.id, attempt=1, worker="w", max_attempts=3, stale_after_s=60)
    assert c is not None and c.attempt == 1
    assert jobs.get_job(sqlite_db, job.id).status == "running"
    # a second delivery while the job is alive (fresh heartbeat) is a duplicate: dropped, no takeover
    assert jobs.claim(sqlite_db, job.id, attempt=1, worker="w2", max_attempts=3, stale_after_s=60) is None
    assert jobs.get_job(sqlite_db, job.id).attempts == 1
    # a redelivery after the worker was lost (stale heartbeat) takes the job over with a new token
    with sqlite_db.write() as s:
        s.execute(update(Job).where(Job.id == job.id).values(heartbeat_at=utcnow() - timedelta(seconds=120)))
    c2 = jobs.claim(sqlite_db, job.id, attempt=1, worker="w2", max_attempts=3, stale_after_s=60)
    assert c2 is not None and c2.attempt == 2
    # the old delivery can no longer write
    assert jobs.heartbeat(sqlite_db, job.id, 1, progress=0.5, message="x") is None
    assert not jobs.finish(sqlite_db, job.id, 1, status="succeeded", result={"x": 1}, error=None, message="done")
    assert jobs.finish(sqlite_db, job.id, 2, status="succeeded", result={"x": 2}, error=None, message="done")
    assert jobs.get_result(sqlite_db, job.id) == {"x": 2}
    final = jobs.get_job(sqlite_db, job.id)
    assert (final.status, final.progress) == ("succeeded", 1.0)


def test_progress_only_grows(sqlite_db):
    job = _new(sqlite_db)
    c = jobs.claim(sqlite_db, job.id, 1, worker="w", max_attempts=3, stale_after_s=60)
    jobs.heartbeat(sqlite_db, job.id, c.attempt, progress=0.6, message="a")
    jobs.heartbeat(sqlite_db, job.id, c.attempt, progress=0.2, message="b")
    j = jobs.get_job(sqlite_db, job.id)
    assert (j.progress, j.message) == (0.6, "b")


def test_cancel_queued_never_starts_and_running_sets_flag(sqlite_db):
    queued = _new(sqlite_db)
    assert jobs.request_cancel(sqlite_db, queued.id).status == "cancelled"
    assert jobs.claim(sqlite_db, queued.id, 1, worker="w", max_attempts=3, stale_after_s=60) is None
    running = _new(sqlite_db)
    c = jobs.claim(sqlite_db, running.id, 1, worker="w", max_attempts=3, stale_after_s=60)
    assert jobs.request_cancel(sqlite_db, running.id).cancel_requested
    assert jobs.heartbeat(sqlite_db, running.id, c.attempt, progress=None, message=None) is True
    assert jobs.request_cancel(sqlite_db, "nope") is None


def test_reaper_requeues_then_fails_after_max_attempts(sqlite_db):
    job = _new(sqlite_db)
    attempt = 1
    for expected in (2, 3):
        assert jobs.claim(sqlite_db, job.id, attempt, worker="w", max_attempts=3, stale_after_s=60) is not None
        with sqlite_db.write() as s:
            s.execute(update(Job).where(Job.id == job.id).values(heartbeat_at=utcnow() - timedelta(seconds=120)))
        requeued = jobs.reap_stale(sqlite_db, stale_after_s=60, max_attempts=3)
        assert [(j.id, j.attempts, j.kind, j.queue) for j in requeued] == [(job.id, expected, "intercept",
                                                                            "trajlab.jobs")]
        attempt = expected
        assert jobs.get_job(sqlite_db, job.id).status == "queued"
    jobs.claim(sqlite_db, job.id, attempt, worker="w", max_attempts=3, stale_after_s=60)
    with sqlite_db.write() as s:
        s.execute(update(Job).where(Job.id == job.id).values(heartbeat_at=utcnow() - timedelta(seconds=120)))
    assert jobs.reap_stale(sqlite_db, stale_after_s=60, max_attempts=3) == []
    j = jobs.get_job(sqlite_db, job.id)
    assert j.status == "failed" and j.error["code"] == "worker_lost" and "3 attempts" in j.error["message"]


def test_fresh_heartbeat_is_not_reaped(sqlite_db):
    job = _new(sqlite_db)
    jobs.claim(sqlite_db, job.id, 1, worker="w", max_attempts=3, stale_after_s=60)
    assert jobs.reap_stale(sqlite_db, stale_after_s=60, max_attempts=3) == []


def test_idempotency_key(sqlite_db):
    a, created = jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None,
                                 idempotency_key="k1", request_hash="h1")
    b, created2 = jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None,
                                  idempotency_key="k1", request_hash="h1")
    assert created and not created2 and a.id == b.id
    with pytest.raises(jobs.IdempotencyConflict):
        jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None,
                        idempotency_key="k1", request_hash="other")


def test_sqlite_concurrent_writers_do_not_fail(sqlite_db):
    """16 threads hammering short write transactions: none may see 'database is locked'."""
    ids = [_new(sqlite_db).id for _ in range(16)]
    for i in ids:
        jobs.claim(sqlite_db, i, 1, worker="w", max_attempts=3, stale_after_s=60)
    errors: list[Exception] = []

    def hammer(job_id):
        try:
            for k in range(30):
                jobs.heartbeat(sqlite_db, job_id, 1, progress=k / 30, message=f"step {k}")
                jobs.list_jobs(sqlite_db, kind=None, status="running", limit=5, offset=0)
        except Exception as exc:  # pragma: no cover - the assertion reports it
            errors.append(exc)

    threads = [threading.Thread(target=hammer, args=(i,)) for i in ids]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert all(abs(jobs.get_job(sqlite_db, i).progress - 29 / 30) < 1e-12 for i in ids)


def test_list_filters_and_paging(sqlite_db):
    for _ in range(5):
        _new(sqlite_db)
    items, total = jobs.list_jobs(sqlite_db, kind="intercept", status="queued", limit=2, offset=1)
    assert total == 5 and len(items) == 2
    assert jobs.list_jobs(sqlite_db, kind="reentry", status=None, limit=10, offset=0)[1] == 0


def test_unpublished_jobs_are_candidates_until_published(sqlite_db):
    job = _new(sqlite_db)
    assert jobs.get_job(sqlite_db, job.id).published_at is not None  # marked in the INSERT
    assert jobs.publish_candidates(sqlite_db, older_than_s=60) == []
    jobs.mark_unpublished(sqlite_db, job.id)  # the broker was down at submission
    j = jobs.get_job(sqlite_db, job.id)
    assert (j.status, j.published_at) == ("queued", None)
    assert [c.id for c in jobs.publish_candidates(sqlite_db, older_than_s=60)] == [job.id]
    jobs.mark_published(sqlite_db, [job.id])
    assert jobs.publish_candidates(sqlite_db, older_than_s=60) == []
    # published long ago and still not claimed: a candidate again (the recovery loop checks the broker)
    with sqlite_db.write() as s:
        s.execute(update(Job).where(Job.id == job.id).values(published_at=utcnow() - timedelta(seconds=120)))
    assert [c.id for c in jobs.publish_candidates(sqlite_db, older_than_s=60)] == [job.id]
    jobs.claim(sqlite_db, job.id, 1, worker="w", max_attempts=3, stale_after_s=60)
    assert jobs.publish_candidates(sqlite_db, older_than_s=60) == []
