"""Deletion, purge, retention, stored bytes and the storage quota on the embedded SQLite database; the
result codec's exactness (issue 27)."""
from __future__ import annotations

import json
import math
from datetime import timedelta

import numpy as np
import pytest
from alembic import command
from sqlalchemy import select, text, update

from app.runtime import result_codec
from app.runtime.migrate import alembic_config, upgrade
from app.runtime.models import Job, StoredResult, Study, utcnow
from app.runtime.settings import Settings
from app.service import jobs, quota, retention, storage


# ----------------------------------------------------------------------------- the codec
def _roundtrip(doc):
    packed, encoding = result_codec.encode(doc)
    back = result_codec.decode(packed, encoding)
    # the same document: equal values, the same types, the same JSON text
    assert json.dumps(back) == json.dumps(doc)
    return packed, back


def test_codec_is_exact_for_every_float_and_keeps_types():
    rng = np.random.default_rng(3)
    smooth = np.cumsum(np.cumsum(rng.normal(size=500))).tolist()
    doc = {
        "smooth": smooth,
        "noise": rng.normal(scale=1e300, size=300).tolist(),       # no structure at all
        "tiny": (rng.normal(size=100) * 1e-310).tolist(),           # subnormals
        "signs": [-0.0, 0.0, math.inf, -math.inf, 5e-324, 1.7976931348623157e308] * 4,
        "gaps": [None if i % 7 == 0 else float(i) ** 0.5 for i in range(50)],
        "ints": list(range(40)),                                    # ints stay ints, never 1.0
        "mixed": [1, 2.0, "x"] * 10,
        "short": [1.5, 2.5],
        "nested": {"rows": [[float(i * j) for j in range(20)] for i in range(20)], 7: "int key"},
        "with_nan": [1.0] * 20 + [math.nan],                        # left as JSON (JSON writes NaN)
        "all_none": [None] * 30,
        "text": "unicode \u00e9\u4e2d",
    }
    packed, back = _roundtrip(doc)
    assert back["ints"] == list(range(40)) and all(type(x) is int for x in back["ints"])
    assert math.copysign(1.0, back["signs"][0]) == -1.0  # -0.0 kept
    assert back["gaps"][0] is None and back["gaps"][1] == 1.0
    assert back["nested"]["7"] == "int key"  # as JSON writes it
    # a sampled smooth curve (what results hold) shrinks past 4x of its JSON; zlib alone gets 2.4x
    curve = (7000.0 * np.sin(np.linspace(0.0, 3.0, 1000)) + 6.4e6).tolist()
    assert len(result_codec.encode({"s": curve})[0]) < len(json.dumps(curve)) / 4


def test_codec_reads_rows_written_before_compression():
    assert result_codec.decode(None, None, {"a": [1.0]}) == {"a": [1.0]}
    with pytest.raises(ValueError, match="unknown result encoding"):
        result_codec.decode(b"", "lz4")


# ----------------------------------------------------------------------------- helpers
def _finished(db, *, owner=None, status="succeeded", result=None, days_ago=0.0, study_id=None, index=None):
    job, _ = jobs.create_job(db, kind="intercept", params={"p": 1}, label=None, preset=None, owner=owner)
    c = jobs.claim(db, job.id, 1, worker="w", max_attempts=3, stale_after_s=60)
    assert jobs.finish(db, c.job_id, 1, status=status, result=result, error=None, message=status)
    when = utcnow() - timedelta(days=days_ago)
    with db.write() as s:
        s.execute(update(Job).where(Job.id == job.id).values(created_at=when, finished_at=when, study_id=study_id,
                                                             study_index=index))
    return job.id


def _count(db, model) -> int:
    with db.read() as s:
        return len(list(s.scalars(select(model))))


RESULT = {"x": [float(i) ** 1.5 for i in range(1000)], "n": 3}


# ----------------------------------------------------------------------------- stored bytes, quota
def test_stored_bytes_follow_writes_and_deletes(sqlite_db):
    job_id = _finished(sqlite_db, owner="ann", result=RESULT)
    _finished(sqlite_db, owner="bob", result={"y": 1.0})
    with sqlite_db.read() as s:
        row = s.get(StoredResult, job_id)
        job = s.get(Job, job_id)
        assert row.data is None and row.encoding == result_codec.ENCODING
        assert job.stored_bytes == len(row.packed) + storage.params_bytes({"p": 1})
    assert jobs.get_result(sqlite_db, job_id) == RESULT
    usage = storage.usage(sqlite_db, Settings(), owner="ann")
    assert (usage["jobs"], usage["jobs_by_status"], usage["stored_bytes"]) == (1, {"succeeded": 1}, job.stored_bytes)
    assert retention.delete_job(sqlite_db, job_id)
    assert storage.usage(sqlite_db, Settings(), owner="ann")["stored_bytes"] == 0
    assert storage.usage(sqlite_db, Settings(), owner="bob")["stored_bytes"] > 0


def test_storage_quota_refuses_a_submission_past_it(sqlite_db):
    settings = Settings(max_stored_mb_per_owner=0.004)  # 4,194 bytes
    big = {"x": np.random.default_rng(1).normal(size=2000).tolist()}  # ~15 kB packed: noise
    with sqlite_db.read() as s:
        quota.check_quota_in(s, settings, owner="ann", cost=1.0)  # nothing stored yet
    job_id = _finished(sqlite_db, owner="ann", result=big)
    with sqlite_db.read() as s, pytest.raises(quota.QuotaExceeded, match="TRAJLAB_MAX_STORED_MB_PER_OWNER"):
        quota.check_quota_in(s, settings, owner="ann", cost=1.0)
    with sqlite_db.read() as s:
        quota.check_quota_in(s, settings, owner="bob", cost=1.0)  # another owner's bytes are not ann's
    retention.delete_job(sqlite_db, job_id)
    with sqlite_db.read() as s:
        quota.check_quota_in(s, settings, owner="ann", cost=1.0)  # deleting frees the quota


# ----------------------------------------------------------------------------- delete
def test_delete_job_cancels_a_running_one_and_removes_its_rows(sqlite_db):
    job, _ = jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None)
    c = jobs.claim(sqlite_db, job.id, 1, worker="w", max_attempts=3, stale_after_s=60)
    assert jobs.heartbeat(sqlite_db, job.id, 1, progress=0.1, message="x") is False
    assert retention.delete_job(sqlite_db, job.id)
    assert jobs.get_job(sqlite_db, job.id) is None
    # the worker: its heartbeat says the job is gone (it stops), and its result is not stored
    assert jobs.heartbeat(sqlite_db, job.id, 1, progress=0.2, message="x") is None
    assert not jobs.finish(sqlite_db, c.job_id, 1, status="succeeded", result=RESULT, error=None, message="done")
    assert _count(sqlite_db, StoredResult) == 0
    assert not retention.delete_job(sqlite_db, job.id)


def _study(db, owner=None, *, status="finished", days_ago=0.0) -> str:
    when = utcnow() - timedelta(days=days_ago)
    with db.write() as s:
        study = Study(kind="intercept", mode="independent", status=status, base_params={}, sweeps=[], points=[],
                      walk={}, owner=owner, cancel_requested=False, created_at=when,
                      finished_at=None if status == "running" else when)
        s.add(study)
        s.flush()
        return study.id


def test_delete_study_removes_its_points(sqlite_db):
    study = _study(sqlite_db)
    points = [_finished(sqlite_db, result=RESULT, study_id=study, index=i) for i in range(3)]
    other = _finished(sqlite_db, result=RESULT)
    assert sorted(retention.delete_study(sqlite_db, study)) == sorted(points)
    assert _count(sqlite_db, Study) == 0
    assert [j.id for j in jobs.list_jobs(sqlite_db, kind=None, status=None, limit=10, offset=0)[0]] == [other]
    assert _count(sqlite_db, StoredResult) == 1
    assert retention.delete_study(sqlite_db, study) is None


# ----------------------------------------------------------------------------- purge, retention
def test_purge_by_age_and_status_and_dry_run(sqlite_db):
    old_ok = _finished(sqlite_db, result=RESULT, days_ago=40)
    old_failed = _finished(sqlite_db, status="failed", days_ago=40)
    _finished(sqlite_db, result=RESULT, days_ago=2)  # too young
    running, _ = jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None)
    with sqlite_db.write() as s:  # an old job still queued is never purged
        s.execute(update(Job).where(Job.id == running.id).values(created_at=utcnow() - timedelta(days=90)))
    old_study = _study(sqlite_db, days_ago=40)
    _finished(sqlite_db, result=RESULT, days_ago=41, study_id=old_study, index=0)
    mixed_study = _study(sqlite_db, days_ago=40)  # a failed point: kept with --status succeeded
    _finished(sqlite_db, result=RESULT, days_ago=41, study_id=mixed_study, index=0)
    _finished(sqlite_db, status="failed", days_ago=41, study_id=mixed_study, index=1)
    _study(sqlite_db, status="running", days_ago=40)

    with pytest.raises(ValueError, match="only finished jobs"):
        retention.purge(sqlite_db, older_than=timedelta(days=30), statuses=["running"])
    month = timedelta(days=30)
    dry = retention.purge(sqlite_db, older_than=month, statuses=["succeeded"], dry_run=True)
    assert (dry["jobs"], dry["studies"]) == (2, 1) and dry["stored_bytes"] > 0
    assert _count(sqlite_db, Job) == 7  # a dry run deletes nothing
    done = retention.purge(sqlite_db, older_than=month, statuses=["succeeded"])
    assert done == dry
    with sqlite_db.read() as s:
        left = set(s.scalars(select(Job.id)))
        assert old_ok not in left and old_failed in left and running.id in left
        assert set(s.scalars(select(Study.id))) >= {mixed_study} and old_study not in set(s.scalars(select(Study.id)))
    assert retention.purge(sqlite_db, older_than=month)["jobs"] == 3  # old_failed and the mixed study's two
    assert _count(sqlite_db, Job) == 2


def test_retention_is_off_unset_and_runs_when_due(sqlite_db):
    old = _finished(sqlite_db, result=RESULT, days_ago=10)
    assert retention.Retention(Settings()).run_if_due(sqlite_db) is None
    keeper = retention.Retention(Settings(retention_days=7, retention_interval_s=3600))
    assert keeper.run_if_due(sqlite_db)["jobs"] == 1
    assert jobs.get_job(sqlite_db, old) is None
    _finished(sqlite_db, result=RESULT, days_ago=10)
    assert keeper.run_if_due(sqlite_db) is None  # not due again within the interval


# ----------------------------------------------------------------------------- migration 0006 with data
def test_migration_0006_keeps_old_results_readable_and_downgrades_without_loss(tmp_path):
    url = f"sqlite:///{tmp_path / 'm.db'}"
    cfg = alembic_config(url)
    command.upgrade(cfg, "0005")
    from app.runtime.db import make_engine

    engine = make_engine(url)
    legacy = {"x": [0.5, 1.5], "n": 1}
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO jobs (id, kind, status, progress, message, params, created_at, attempts, "
                          "cancel_requested, queue) VALUES ('a' || hex(randomblob(15)), 'intercept', 'succeeded', "
                          "1.0, 'done', '{\"p\": 1}', '2026-01-01 00:00:00', 1, 0, 'trajlab.jobs')"))
        old_id = conn.execute(text("SELECT id FROM jobs")).scalar()
        conn.execute(text("INSERT INTO job_results (job_id, data, created_at) VALUES (:id, :d, '2026-01-01')"),
                     {"id": old_id, "d": json.dumps(legacy)})
    upgrade(url)
    from app.runtime.db import get_database

    db = get_database(url)
    assert jobs.get_result(db, old_id) == legacy
    with db.read() as s:
        assert s.get(Job, old_id).stored_bytes == len('{"p": 1}') + len(json.dumps(legacy))
    new_id = _finished(db, result=RESULT)
    command.downgrade(cfg, "0005")
    with engine.connect() as conn:
        rows = dict(conn.execute(text("SELECT job_id, data FROM job_results")).all())
    assert json.loads(rows[old_id]) == legacy and json.loads(rows[new_id]) == RESULT
    upgrade(url)
    assert jobs.get_result(db, new_id) == RESULT
    db.dispose()
    engine.dispose()


def test_purge_command(sqlite_db, monkeypatch, capsys):
    from app.cli.commands import main
    from app.runtime.settings import get_settings

    old = _finished(sqlite_db, result=RESULT, days_ago=40)
    young = _finished(sqlite_db, result=RESULT, days_ago=1)
    monkeypatch.setenv("TRAJLAB_DATABASE_URL", sqlite_db.url)
    get_settings.cache_clear()
    try:
        assert main(["purge", "--older-than", "30", "--dry-run"]) == 0
        assert "would delete 1 job(s)" in capsys.readouterr().out and jobs.get_job(sqlite_db, old) is not None
        assert main(["purge", "--older-than", "30", "--status", "succeeded,running"]) == 2
        assert "only finished jobs can be purged" in capsys.readouterr().err
        assert main(["purge", "--older-than", "30", "--status", "failed"]) == 0
        assert jobs.get_job(sqlite_db, old) is not None  # not failed
        assert main(["purge", "--older-than", "30"]) == 0
        assert "deleted 1 job(s)" in capsys.readouterr().out
        assert jobs.get_job(sqlite_db, old) is None and jobs.get_job(sqlite_db, young) is not None
    finally:
        get_settings.cache_clear()
