"""Deleting jobs and studies, and purging old ones: ``DELETE /v1/jobs/{id}``, ``DELETE /v1/studies/{id}``,
``trajlab purge`` and ``TRAJLAB_RETENTION_DAYS`` (issue 27).

A job's data is its row, its result row and nothing else in the database (its progress events are
read from the row; the API's rendered plots are cached per process and keyed by job, and the route
drops them).  Deleting a job that is queued or running goes through the cancel path first
(:func:`app.service.jobs.request_cancel`); once the row is gone the worker's next heartbeat finds
no job, its solver stops at the next iteration and it stores nothing (``jobs.finish`` finds no row),
and a message still in the broker is dropped at claim.  The result row goes in the same
transaction (and by ``ON DELETE CASCADE`` if a worker's store races the delete).

A study is deleted whole, with every point job.  Purging takes finished jobs that are not points of
a study, and finished studies every one of whose points has a status purged, in batches of
:data:`BATCH` rows per transaction, so a large purge never holds SQLite's write lock for long.
"""
from __future__ import annotations

import logging
import time
from datetime import datetime, timedelta

from sqlalchemy import delete, exists, func, select
from sqlalchemy.orm import Session

from app.service import jobs, studies
from app.runtime.db import Database
from app.runtime.models import FINAL_STATUSES, Job, StoredResult, Study, utcnow
from app.runtime.settings import Settings

log = logging.getLogger("trajlab.retention")
BATCH = 500
STUDY_BATCH = 20  # a study has up to studies.MAX_POINTS points


def _delete_rows(s: Session, job_ids: list[str]) -> None:
    if job_ids:
        s.execute(delete(StoredResult).where(StoredResult.job_id.in_(job_ids)))
        s.execute(delete(Job).where(Job.id.in_(job_ids)))


def delete_job(db: Database, job_id: str) -> bool:
    """Cancel (if it is queued or running) and delete a job with its result; False if there is none."""
    if jobs.request_cancel(db, job_id) is None:
        return False
    with db.write() as s:
        found = s.get(Job, job_id) is not None
        _delete_rows(s, [job_id])
    return found


def delete_study(db: Database, study_id: str) -> list[str] | None:
    """Cancel a study and delete it with every point job; the ids deleted, or None if there is none."""
    studies.request_cancel(db, study_id)  # flags the study: nothing advances it past this point
    with db.write() as s:
        study = s.scalar(select(Study).where(Study.id == study_id).with_for_update())
        if study is None:
            return None
        ids = list(s.scalars(select(Job.id).where(Job.study_id == study_id)))
        _delete_rows(s, ids)
        s.delete(study)
    return ids


def _check_statuses(statuses) -> tuple[str, ...]:
    statuses = tuple(dict.fromkeys(statuses))
    wrong = [x for x in statuses if x not in FINAL_STATUSES]
    if wrong or not statuses:
        raise ValueError(f"only finished jobs can be purged: statuses must be among {', '.join(FINAL_STATUSES)}"
                         f" (got {', '.join(wrong) or 'none'})")
    return statuses


def purge(db: Database, *, older_than: timedelta, statuses=FINAL_STATUSES, dry_run: bool = False,
          now: datetime | None = None) -> dict:
    """Delete jobs that finished more than ``older_than`` ago with one of ``statuses``, and finished
    studies of that age all of whose points have one of them (with their points).  Returns the counts
    (``jobs``, ``studies``, ``stored_bytes`` freed); ``dry_run`` counts without deleting."""
    statuses = _check_statuses(statuses)
    cutoff = (now or utcnow()) - older_than
    lone = (Job.study_id.is_(None), Job.status.in_(statuses), Job.finished_at < cutoff)
    # a point whose status is not purged keeps its whole study
    kept_point = exists().where(Job.study_id == Study.id, Job.status.not_in(statuses))
    old_study = (Study.status != "running", Study.finished_at < cutoff, ~kept_point)
    done = {"jobs": 0, "studies": 0, "stored_bytes": 0}
    if dry_run:
        with db.read() as s:
            n, size = s.execute(select(func.count(), func.coalesce(func.sum(Job.stored_bytes), 0)).where(*lone)).one()
            in_studies = select(Study.id).where(*old_study)
            m, n_points, points_size = s.execute(select(
                select(func.count()).select_from(in_studies.subquery()).scalar_subquery(),
                func.count(Job.id), func.coalesce(func.sum(Job.stored_bytes), 0)).where(
                Job.study_id.in_(in_studies))).one()
        return {"jobs": int(n) + int(n_points), "studies": int(m), "stored_bytes": int(size) + int(points_size)}
    while True:
        with db.write() as s:
            rows = s.execute(select(Job.id, Job.stored_bytes).where(*lone).limit(BATCH)).all()
            _delete_rows(s, [r.id for r in rows])
        done["jobs"] += len(rows)
        done["stored_bytes"] += sum(int(r.stored_bytes) for r in rows)
        if len(rows) < BATCH:
            break
    while True:
        with db.write() as s:
            ids = list(s.scalars(select(Study.id).where(*old_study).limit(STUDY_BATCH)))
            points = s.execute(select(Job.id, Job.stored_bytes).where(Job.study_id.in_(ids))).all() if ids else []
            _delete_rows(s, [r.id for r in points])
            if ids:
                s.execute(delete(Study).where(Study.id.in_(ids)))
        done["studies"] += len(ids)
        done["jobs"] += len(points)
        done["stored_bytes"] += sum(int(r.stored_bytes) for r in points)
        if len(ids) < STUDY_BATCH:
            break
    return done


class Retention:
    """``TRAJLAB_RETENTION_DAYS`` applied by the recovery loop, at most every ``retention_interval_s``."""

    def __init__(self, settings: Settings):
        self.settings = settings
        self._next = 0.0

    def run_if_due(self, db: Database) -> dict | None:
        """The purge's counts when it ran, None when retention is off or not due yet."""
        days = self.settings.retention_days
        if days is None or time.monotonic() < self._next:
            return None
        done = purge(db, older_than=timedelta(days=days))
        self._next = time.monotonic() + self.settings.retention_interval_s  # after a success only
        if done["jobs"] or done["studies"]:
            log.info("retention (%g days): deleted %d job(s) and %d study(ies), %d bytes", days, done["jobs"],
                     done["studies"], done["stored_bytes"])
        return done
