"""POST /v1/jobs admits a job in one transaction (idempotency lookup, quota, insert): a repeated submission
is answered at the quota limit, new work past it is a 429 that stores nothing, and a key of another owner
is a conflict."""
from __future__ import annotations

from fastapi.testclient import TestClient
from sqlalchemy import func, select

from app.api import auth
from app.api.main import create_app
from app.runtime.migrate import upgrade
from app.runtime.models import Job
from app.runtime.settings import Settings

BODY = {"kind": "intercept", "preset": "long-range-intercept", "params": {"methods": ["impulsive"]}}


def test_repeat_at_the_limit_is_answered_new_work_is_429_and_nothing_is_stored(tmp_path):
    url = f"sqlite:///{tmp_path / 'adm.db'}"
    upgrade(url)
    # the broker is unreachable: accepted jobs stay queued (unpublished), which is what the quota counts
    app = create_app(Settings(database_url=url, broker_url="redis://127.0.0.1:1/0", auth="required",
                              max_queued_per_owner=2))
    with TestClient(app) as client:
        db = app.state.db
        _, dana = auth.create_key(db, name="dana")
        _, emil = auth.create_key(db, name="emil")
        h = {"Authorization": f"Bearer {dana}"}
        first = client.post("/v1/jobs", json=BODY, headers={**h, "Idempotency-Key": "a"})
        second = client.post("/v1/jobs", json=BODY, headers={**h, "Idempotency-Key": "b"})
        assert first.status_code == second.status_code == 202
        again = client.post("/v1/jobs", json=BODY, headers={**h, "Idempotency-Key": "a"})
        assert again.status_code == 202 and again.json()["id"] == first.json()["id"]  # at the limit, still answered
        assert again.headers["Location"] == f"/v1/jobs/{first.json()['id']}"
        over = client.post("/v1/jobs", json=BODY, headers={**h, "Idempotency-Key": "c"})
        assert over.status_code == 429 and "TRAJLAB_MAX_QUEUED_PER_OWNER" in over.json()["detail"]
        other = client.post("/v1/jobs", json=BODY, headers={"Authorization": f"Bearer {emil}",
                                                            "Idempotency-Key": "a"})
        assert other.status_code == 422  # dana's key: a conflict, never dana's job
        with db.read() as s:
            assert s.scalar(select(func.count()).select_from(Job)) == 2
            assert s.scalar(select(func.count()).select_from(Job).where(Job.idempotency_key == "c")) == 0
