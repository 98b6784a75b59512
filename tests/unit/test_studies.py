"""Studies on SQLite, no broker: sweeps expand to points; the continuation walk warm-starts from the nearest
solved neighbour, comes back from the other end to retry failures from their other neighbour, and closes."""
from __future__ import annotations

import pytest

from app.service import jobs, studies


@pytest.fixture
def db(sqlite_db):
    return sqlite_db


BASE = {"grid": {"intervals": 20}, "path": {"max_heat_rate_w_m2": None}, "initial_guess": {"from_job": None}}


def test_sweep_values_and_cartesian_points():
    assert studies.sweep_values({"path": "a", "start": 0.0, "stop": 1.0, "count": 3}) == [0.0, 0.5, 1.0]
    pts = studies.expand({"a": 0, "g": {"b": 0, "c": 0}},
                         [{"path": "a", "values": [1, 2]}, {"path": ["g.b", "g.c"], "values": [5, 6, 7]}])
    assert len(pts) == 6 and pts[0].values == {"a": 1, "g.b & g.c": 5}
    assert pts[5].params == {"a": 2, "g": {"b": 7, "c": 7}}
    with pytest.raises(KeyError):
        studies.expand({"a": 0}, [{"path": "nope", "values": [1]}])
    with pytest.raises(KeyError):
        studies.expand({"a": 0}, [{"path": "a.b", "values": [1]}])
    # an element of a list parameter, by index
    pts = studies.expand({"tf_bounds_s": [2000.0, 6000.0]}, [{"path": "tf_bounds_s.1", "values": [7000.0]}])
    assert pts[0].params == {"tf_bounds_s": [2000.0, 7000.0]} and pts[0].values == {"tf_bounds_s.1": 7000.0}
    with pytest.raises(KeyError):
        studies.expand({"tf_bounds_s": [2000.0, 6000.0]}, [{"path": "tf_bounds_s.2", "values": [1.0]}])


def _finish(db, job, status):
    claim = jobs.claim(db, job.id, job.attempts, worker="t", max_attempts=3, stale_after_s=60)
    assert claim is not None
    jobs.finish(db, job.id, claim.attempt, status=status, result={"objective": {"value": 1.0}} if status == "succeeded" else None,
                error=None if status == "succeeded" else {"code": "infeasible", "message": "x"}, message=status)


def test_continuation_walk_forward_then_back(db):
    sweeps = [{"path": "path.max_heat_rate_w_m2", "values": [4.0, 3.0, 2.0, 1.0]}]
    points = studies.expand(BASE, sweeps)
    study, created = studies.create_study(db, kind="reentry", preset=None, label="t", base_params=BASE,
                                          sweeps=sweeps, mode="continuation", points=points, owner=None,
                                          queue="trajlab.jobs")
    assert len(created) == 1 and created[0].study_index == 0
    assert created[0].params["initial_guess"]["from_job"] is None  # the first point starts cold
    assert studies.advance(db, study.id) == []  # point 0 still queued: nothing new
    outcomes = {0: "succeeded", 1: "failed", 2: "succeeded", 3: "failed"}
    order, job = [], created[0]
    while job is not None:
        order.append((job.study_index, job.params["initial_guess"]["from_job"]))
        status = outcomes[job.study_index]
        if len(order) > 4 and job.study_index == 1:
            status = "succeeded"  # the retry from the right-hand neighbour solves it
        _finish(db, job, status)
        nxt = studies.advance(db, study.id)
        job = nxt[0] if nxt else None
    by_index = {}
    for j in studies.point_jobs(db, study.id):
        by_index.setdefault(j.study_index, []).append(j)
    first = {i: js[0].id for i, js in by_index.items()}
    # forward: 1 from 0, 2 from 0 (1 failed: nearest solved on the left), 3 from 2; back: 1 retried from 2
    assert order == [(0, None), (1, first[0]), (2, first[0]), (3, first[2]), (1, first[2])]
    rows = studies.trade_table(db, studies.get_study(db, study.id))
    assert [r["status"] for r in rows] == ["succeeded", "succeeded", "succeeded", "failed"]
    assert rows[3]["error_code"] == "infeasible"
    summary = studies.summary(db, studies.get_study(db, study.id))
    assert summary["status"] == "finished" and summary["progress"] == 1.0


def test_cancel_cancels_queued_points(db):
    sweeps = [{"path": "path.max_heat_rate_w_m2", "values": [4.0, 3.0, 2.0]}]
    study, created = studies.create_study(db, kind="reentry", preset=None, label=None, base_params=BASE,
                                          sweeps=sweeps, mode="independent", points=studies.expand(BASE, sweeps),
                                          owner="o", queue="trajlab.jobs")
    assert len(created) == 3
    _finish(db, created[0], "succeeded")
    studies.request_cancel(db, study.id)
    statuses = sorted(j.status for j in studies.point_jobs(db, study.id))
    assert statuses == ["cancelled", "cancelled", "succeeded"]
    assert studies.get_study(db, study.id).status == "cancelled"


def test_independent_study_retries_a_failed_point_from_a_solved_neighbour(db):
    sweeps = [{"path": "path.max_heat_rate_w_m2", "values": [4.0, 3.0, 2.0]}]
    study, created = studies.create_study(db, kind="reentry", preset=None, label=None, base_params=BASE,
                                          sweeps=sweeps, mode="independent", points=studies.expand(BASE, sweeps),
                                          owner=None, queue="trajlab.jobs")
    for job, status in zip(created, ("succeeded", "failed", "failed")):
        _finish(db, job, status)
        retries = studies.advance(db, study.id)
    # point 1 from point 0; point 2 has no solved neighbour yet
    assert [(j.study_index, j.params["initial_guess"]["from_job"]) for j in retries] == [(1, created[0].id)]
    _finish(db, retries[0], "succeeded")
    again = studies.advance(db, study.id)
    assert [(j.study_index, j.params["initial_guess"]["from_job"]) for j in again] == [(2, retries[0].id)]
    _finish(db, again[0], "failed")
    assert studies.advance(db, study.id) == []  # tried from every solved neighbour: the failure is the answer
    rows = studies.trade_table(db, studies.get_study(db, study.id))
    assert [r["status"] for r in rows] == ["succeeded", "succeeded", "failed"]
    assert studies.get_study(db, study.id).status == "finished"
