"""Trade studies: one parameter (or two) swept over a base job, each point an ordinary job.

A study row holds the base job (kind, preset, resolved params), the sweeps and
the mode; its points are rows of ``jobs`` with ``study_id``/``study_index``, so
progress, cancel, the reaper and results hold for them as for any job.

* ``independent``: every point is created and published at once; the workers
  that are free run them, each from its own cold start.  Once all are final, a
  failed point is retried, warm-started from a solved neighbour (once per
  neighbour); one that still fails is an answer (e.g. infeasible).
* ``continuation``: points run one at a time in sweep order, each warm-started
  from the nearest point already solved (the kind's ``from_job`` field).  After
  the forward walk, the walk comes back from the other end and retries each
  failed point from its other (right-hand) neighbour, if that one solved.

:func:`advance` moves a continuation study on; it is called by the worker as
soon as a point finishes and by the recovery loop as a backstop, and it is safe
to call twice (the study row is locked while it decides).
"""
from __future__ import annotations

import copy
import itertools
from dataclasses import dataclass
from typing import Iterator

import numpy as np
from sqlalchemy import select

from app.runtime.db import Database
from app.runtime.models import FINAL_STATUSES, Job, StoredResult, Study, utcnow
from app.service import jobs, storage
from app.service.summary import FIXED_OBJECTIVE, WARM_START_FIELD, key_numbers

MAX_POINTS = 200


@dataclass
class Point:
    index: int
    values: dict            # swept path -> value
    params: dict            # fully resolved params of the point


def sweep_values(sweep: dict) -> list:
    """A sweep's values: the list given, or ``count`` values from ``start`` to ``stop`` inclusive."""
    if sweep.get("values") is not None:
        return list(sweep["values"])
    return [float(v) for v in np.linspace(sweep["start"], sweep["stop"], int(sweep["count"]))]


def sweep_paths(sweep: dict) -> list[str]:
    path = sweep["path"]
    return [path] if isinstance(path, str) else list(path)


def _step(node, part: str, path: str):
    if isinstance(node, list) and part.isdigit() and int(part) < len(node):
        return int(part)  # an element of a list parameter, e.g. tf_bounds_s.1
    if isinstance(node, list):  # an element by its name, e.g. an ocp phase: phases.coast.time.final_upper
        named = [i for i, item in enumerate(node) if isinstance(item, dict) and item.get("name") == part]
        if len(named) == 1:
            return named[0]
    if isinstance(node, dict) and part in node:
        return part
    raise KeyError(f"{path}: no parameter {part}")


def set_path(params: dict, path: str, value) -> None:
    """Set a dotted path inside ``params`` (list elements by index); every step must already exist."""
    node = params
    *groups, leaf = path.split(".")
    for g in groups:
        node = node[_step(node, g, path)]
        if not isinstance(node, (dict, list)):
            raise KeyError(f"{path}: {g} is not a parameter group")
    node[_step(node, leaf, path)] = value


def get_path(params: dict, path: str):
    node = params
    for part in path.split("."):
        node = node[_step(node, part, path)]
    return node


def expand(base_params: dict, sweeps: list[dict]) -> list[Point]:
    """The study's points (cartesian product of the sweeps, first sweep slowest), params not yet validated."""
    axes = [[(sweep, v) for v in sweep_values(sweep)] for sweep in sweeps]
    points = []
    for index, combo in enumerate(itertools.product(*axes)):
        params = copy.deepcopy(base_params)
        values = {}
        for sweep, value in combo:
            for path in sweep_paths(sweep):
                set_path(params, path, value)
            values[" & ".join(sweep_paths(sweep))] = value
        points.append(Point(index, values, params))
    return points


def _point_job(study: Study, point_index: int, params: dict, values: dict) -> Job:
    label = f"{study.label or 'study ' + study.id[:8]} [{point_index}] " + \
        ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in values.items())
    # the caller publishes right after the commit
    return Job(**jobs.queued_job_values(kind=study.kind, params=params, label=label[:200], preset=study.preset,
                                        owner=study.owner, queue=study.queue, study_id=study.id,
                                        study_index=point_index))


def create_study(db: Database, *, kind: str, preset: str | None, label: str | None, base_params: dict,
                 sweeps: list[dict], mode: str, points: list[Point], owner: str | None,
                 queue: str) -> tuple[Study, list[Job]]:
    """Store the study; an independent study stores all its point jobs at once (publish them after)."""
    with db.write() as s:
        study = Study(kind=kind, preset=preset, label=label, base_params=base_params, sweeps=sweeps, mode=mode,
                      status="running", owner=owner, queue=queue, cancel_requested=False, created_at=utcnow(),
                      points=[{"index": p.index, "values": p.values, "params": p.params} for p in points],
                      walk={"phase": "forward", "cursor": 0})
        s.add(study)
        s.flush()
        created = []
        if mode == "independent":
            for p in points:
                job = _point_job(study, p.index, p.params, p.values)
                s.add(job)
                created.append(job)
    if mode == "continuation":
        created = advance(db, study.id)
    return study, created


def point_jobs(db: Database, study_id: str) -> list[Job]:
    with db.read() as s:
        return list(s.scalars(select(Job).where(Job.study_id == study_id).order_by(Job.created_at, Job.id)))


def latest_by_index(jobs_: list[Job]) -> dict[int, Job]:
    """The last job of each point (a retried point has several)."""
    out: dict[int, Job] = {}
    for job in jobs_:
        assert job.study_index is not None  # a study's jobs carry their point's index
        out[job.study_index] = job
    return out


def objective_values(session, kind: str, jobs_: list[Job]) -> dict[str, float]:
    """The fixed-direction objective (FIXED_OBJECTIVE) of each succeeded job, signed so that lower is better."""
    if kind not in FIXED_OBJECTIVE:
        return {}
    path, sense = FIXED_OBJECTIVE[kind]
    out = {}
    for job in jobs_:
        row = session.get(StoredResult, job.id) if job.status == "succeeded" else None
        try:
            value = float(get_path(storage.read_result(row) or {}, path)) if row is not None else None
        except (KeyError, TypeError, ValueError):
            value = None
        if value is not None:
            out[job.id] = value if sense == "min" else -value
    return out


def best_by_index(jobs_: list[Job], values: dict[str, float]) -> dict[int, Job]:
    """Each point's job to report: the best succeeded one by the fixed objective, else the last."""
    out = latest_by_index(jobs_)
    for job in jobs_:
        assert job.study_index is not None  # a study's jobs carry their point's index
        cur = out[job.study_index]
        if job.id in values and (cur.id not in values or values[job.id] < values[cur.id]):
            out[job.study_index] = job
    return out


def _warm(study: Study, params: dict, source: Job | None) -> dict:
    params = copy.deepcopy(params)
    field = WARM_START_FIELD.get(study.kind)
    if field and source is not None:
        set_path(params, field, source.id)
    return params


def advance(db: Database, study_id: str) -> list[Job]:
    """Move a continuation study on by at most one point; the new job (to publish) or nothing."""
    with db.write() as s:
        study = s.scalar(select(Study).where(Study.id == study_id).with_for_update())
        if study is None or study.status != "running":
            return []
        rows = list(s.scalars(select(Job).where(Job.study_id == study_id).order_by(Job.created_at, Job.id)))
        latest = latest_by_index(rows)
        if study.cancel_requested:
            _close(study)
            return []
        if study.mode == "independent":
            if len(latest) < len(study.points) or any(j.status not in FINAL_STATUSES for j in latest.values()):
                return []
            retries = _retries_from_neighbours(study, rows, latest) or _polish(study, rows,
                                                                                 objective_values(s, study.kind, rows))
            if not retries:
                _close(study)
            for job in retries:
                s.add(job)
            return retries
        if any(j.status not in FINAL_STATUSES for j in latest.values()):
            return []  # a point is queued or running: wait for it
        n = len(study.points)
        walk = dict(study.walk)
        succeeded = {i: j for i, j in latest.items() if j.status == "succeeded"}
        while True:
            i = walk["cursor"]
            if walk["phase"] == "forward":
                if i >= n:
                    walk = {"phase": "backward", "cursor": n - 2}
                    continue
                if i in latest:
                    walk["cursor"] = i + 1
                    continue
                left = [k for k in succeeded if k < i]
                source = succeeded[max(left)] if left else None
                point = study.points[i]
                job = _point_job(study, i, _warm(study, point["params"], source), point["values"])
            else:
                if i < 0:
                    _close(study)
                    study.walk = walk
                    return []
                job_i, right = latest.get(i), succeeded.get(i + 1)
                field = WARM_START_FIELD.get(study.kind)
                tried_from_right = (job_i is not None and field is not None and right is not None
                                    and _from_job(job_i.params, field) == right.id)
                if job_i is None or job_i.status == "succeeded" or right is None or field is None or tried_from_right:
                    walk["cursor"] = i - 1
                    continue
                point = study.points[i]
                job = _point_job(study, i, _warm(study, point["params"], right), point["values"])
                walk["cursor"] = i - 1  # after this retry, go on down (it may seed the next one)
            s.add(job)
            study.walk = walk
            return [job]


def _retries_from_neighbours(study: Study, rows: list[Job], latest: dict[int, Job]) -> list[Job]:
    """Independent study, every point final: each failed point once more, warm-started from a solved
    neighbour it was not yet tried from.  A point that still fails is an answer (e.g. infeasible)."""
    field = WARM_START_FIELD.get(study.kind)
    if field is None:
        return []
    succeeded = {i: j for i, j in latest.items() if j.status == "succeeded"}
    retries = []
    for i, job in sorted(latest.items()):
        if job.status != "failed":
            continue
        tried = {_from_job(j.params, field) for j in rows if j.study_index == i}
        source = next((succeeded[k] for k in (i - 1, i + 1) if k in succeeded and succeeded[k].id not in tried),
                      None)
        if source is not None:
            point = study.points[i]
            retries.append(_point_job(study, i, _warm(study, point["params"], source), point["values"]))
    return retries


def _polish(study: Study, rows: list[Job], values: dict[str, float]) -> list[Job]:
    """Retry each point from a neighbour whose best answer beats its own (once per source job)."""
    field = WARM_START_FIELD.get(study.kind)
    if field is None or not values:
        return []
    best = best_by_index(rows, values)
    retries = []
    for i, job in sorted(best.items()):
        tried = {_from_job(j.params, field) for j in rows if j.study_index == i}
        for k in (i - 1, i + 1):
            src = best.get(k)
            if (src is not None and src.id in values and src.id not in tried
                    and (job.id not in values or values[src.id] < values[job.id] - 1e-6 * abs(values[src.id]))):
                point = study.points[i]
                retries.append(_point_job(study, i, _warm(study, point["params"], src), point["values"]))
                break
    return retries


def _from_job(params: dict, field: str):
    try:
        return get_path(params, field)
    except (KeyError, TypeError):
        return None


def _close(study: Study) -> None:
    study.status = "cancelled" if study.cancel_requested else "finished"
    study.finished_at = utcnow()


def request_cancel(db: Database, study_id: str) -> list[str]:
    """Flag the study and cancel its unfinished points; the ids of the points cancelled or flagged."""
    with db.write() as s:
        study = s.scalar(select(Study).where(Study.id == study_id).with_for_update())
        if study is None:
            return []
        study.cancel_requested = True
        if study.status == "running":
            study.status = "cancelled"
            study.finished_at = utcnow()
        pending = [j.id for j in s.scalars(select(Job).where(Job.study_id == study_id,
                                                              Job.status.in_(("queued", "running"))))]
    for job_id in pending:
        jobs.request_cancel(db, job_id)
    return pending


def get_study(db: Database, study_id: str) -> Study | None:
    with db.read() as s:
        return s.get(Study, study_id)


def list_studies(db: Database, *, owner: str | None, limit: int, offset: int) -> list[Study]:
    """Newest first; ``owner`` None lists every owner's (admins, auth off)."""
    with db.read() as s:
        q = select(Study)
        if owner is not None:
            q = q.where(Study.owner == owner)
        return list(s.scalars(q.order_by(Study.created_at.desc(), Study.id.desc()).limit(limit).offset(offset)))


def summary(db: Database, study: Study) -> dict:
    all_jobs = point_jobs(db, study.id)
    with db.read() as session:
        latest = best_by_index(all_jobs, objective_values(session, study.kind, all_jobs))
    n = len(study.points)
    done = sum(1 for j in latest.values() if j.status in FINAL_STATUSES)
    counts: dict[str, int] = {}
    for j in latest.values():
        counts[j.status] = counts.get(j.status, 0) + 1
    status = study.status
    return {"id": study.id, "kind": study.kind, "label": study.label, "preset": study.preset, "mode": study.mode,
            "status": status, "progress": done / n if n else 1.0, "points": n, "points_by_status": counts,
            "sweeps": study.sweeps, "base_params": study.base_params,
            "created_at": study.created_at.isoformat() if study.created_at else None,
            "finished_at": study.finished_at.isoformat() if study.finished_at else None}


def trade_table(db: Database, study: Study) -> list[dict]:
    """One row per point: swept values, status, the kind's key numbers, the job id (and warm start source)."""
    return [row for row, _ in trade_rows(db, study)]


def trade_rows(db: Database, study: Study) -> Iterator[tuple[dict, dict | None]]:
    """Each point's :func:`trade_table` row with the result its key numbers were read from (a succeeded
    point's; None for the others), one at a time: a study's results together may be large."""
    all_jobs = point_jobs(db, study.id)
    with db.read() as session:
        latest = best_by_index(all_jobs, objective_values(session, study.kind, all_jobs))
    field = WARM_START_FIELD.get(study.kind)
    for point in study.points:
        job = latest.get(point["index"])
        row = {"index": point["index"], **point["values"], "status": job.status if job else "pending",
               "job_id": job.id if job else None,
               "jobs": sum(1 for j in all_jobs if j.study_index == point["index"])}
        result = None
        if job is not None:
            if field:
                row["warm_start_from"] = _from_job(job.params, field)
            if job.status == "succeeded":
                result = jobs.get_result(db, job.id)
                row.update(key_numbers(study.kind, result))
            elif job.error:
                row["error_code"] = job.error.get("code")
        yield row, result


def on_point_finished(db: Database, job_id: str) -> list[Job]:
    """Called by the worker when a job finished: the next point of its continuation study, if any (to publish)."""
    job = jobs.get_job(db, job_id)
    if job is None or job.study_id is None:
        return []
    return advance(db, job.study_id)


def advance_all(db: Database) -> list[Job]:
    """Backstop for the recovery loop: move on every running study whose points are all final."""
    with db.read() as s:
        ids = list(s.scalars(select(Study.id).where(Study.status == "running")))
    created: list[Job] = []
    for study_id in ids:
        created += advance(db, study_id)
    return created
