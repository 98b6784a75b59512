"""Keys, owners, quotas and input limits without a broker (SQLite, TestClient, TRAJLAB_AUTH=required).

The same rules over HTTP against PostgreSQL, Redis and real workers are in
tests/integration/test_security.py.
"""
from __future__ import annotations

import hashlib
import json

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from app.api import auth
from app.service import jobs, quota
from app.service.broker import QUEUE_HEAVY, QUEUE_JOBS
from app.kinds import KINDS, PRESETS
from app.api.limits import count_lambert_problems, unsafe_text
from app.api.main import create_app
from app.runtime.migrate import upgrade
from app.runtime.models import ApiKey, Job
from app.service.params import resolve_params
from app.runtime.settings import Settings


def preset_params(name: str) -> dict:
    return resolve_params(KINDS[PRESETS[name].kind], PRESETS[name].params, None)


@pytest.fixture(scope="module")
def stack(tmp_path_factory):
    url = f"sqlite:///{tmp_path_factory.mktemp('sec') / 'sec.db'}"
    upgrade(url)
    # Nothing here reaches the broker: every submission is refused before publishing.
    settings = Settings(database_url=url, broker_url="redis://127.0.0.1:1/0", auth="required",
                        max_body_bytes=100_000, lambert_max_problems=10, max_queued_per_owner=2)
    app = create_app(settings)

    @app.get("/boom", include_in_schema=False)
    def boom():
        raise RuntimeError("secret at postgresql://admin:hunter2@10.0.0.5/db")

    with TestClient(app, raise_server_exceptions=False) as client:
        db = app.state.db
        _, alice = auth.create_key(db, name="alice")
        _, bob = auth.create_key(db, name="bob")
        _, ops = auth.create_key(db, name="ops", admin=True)
        yield client, db, {"alice": alice, "bob": bob, "ops": ops}


def bearer(key: str) -> dict:
    return {"Authorization": f"Bearer {key}"}


def test_only_the_sha256_of_a_key_is_stored(stack):
    _, db, keys = stack
    key = keys["alice"]
    assert key.startswith("tl_") and len(key) >= 43
    with db.read() as s:
        row = s.scalar(select(ApiKey).where(ApiKey.name == "alice"))
    assert row.key_hash == hashlib.sha256(key.encode()).hexdigest()
    assert key not in {str(v) for v in vars(row).values()}
    assert row.owner == "alice" and not row.admin


def test_no_key_or_a_wrong_key_is_401_with_a_bearer_challenge(stack):
    client, _, keys = stack
    r = client.get("/v1/jobs")
    assert r.status_code == 401 and r.headers["WWW-Authenticate"] == "Bearer"
    r = client.get("/v1/jobs", headers=bearer(keys["alice"] + "x"))
    assert r.status_code == 401 and r.headers["WWW-Authenticate"].startswith("Bearer error=")
    assert client.get("/v1/jobs", headers=bearer(keys["alice"])).status_code == 200
    assert client.get("/healthz").status_code == 200  # liveness needs no key


def test_owners_see_only_their_jobs_and_admins_see_all(stack):
    client, db, keys = stack
    a, _ = jobs.create_job(db, kind="intercept", params={}, label="a", preset=None, owner="alice")
    b, _ = jobs.create_job(db, kind="intercept", params={}, label="b", preset=None, owner="bob")
    listed = {j["id"] for j in client.get("/v1/jobs?limit=500", headers=bearer(keys["alice"])).json()["items"]}
    assert a.id in listed and b.id not in listed
    assert client.get(f"/v1/jobs/{b.id}", headers=bearer(keys["alice"])).status_code == 404
    assert client.post(f"/v1/jobs/{b.id}/cancel", headers=bearer(keys["alice"])).status_code == 404
    assert jobs.get_job(db, b.id).status == "queued"
    admin = {j["id"] for j in client.get("/v1/jobs?limit=500", headers=bearer(keys["ops"])).json()["items"]}
    assert {a.id, b.id} <= admin
    assert client.get(f"/v1/jobs/{b.id}", headers=bearer(keys["ops"])).json()["label"] == "b"


def test_a_revoked_key_is_refused_on_its_next_request(stack):
    client, db, _ = stack
    _, key = auth.create_key(db, name="temp")
    assert client.get("/v1/jobs", headers=bearer(key)).status_code == 200
    assert auth.revoke_key(db, "temp")
    assert client.get("/v1/jobs", headers=bearer(key)).status_code == 401


def test_openapi_declares_the_bearer_scheme(stack):
    client, _, _ = stack
    doc = client.get("/openapi.json").json()
    schemes = doc["components"]["securitySchemes"]
    assert any(s["type"] == "http" and s["scheme"] == "bearer" for s in schemes.values())  # /docs: Authorize
    assert doc["paths"]["/v1/jobs"]["post"]["security"]


def test_quota_of_queued_jobs_is_429_with_retry_after(stack):
    client, db, keys = stack
    for _ in range(2):
        jobs.create_job(db, kind="intercept", params={}, label=None, preset=None, owner="carol")
    _, carol = auth.create_key(db, name="carol")
    r = client.post("/v1/jobs", json={"kind": "intercept", "preset": "long-range-intercept"}, headers=bearer(carol))
    assert r.status_code == 429 and int(r.headers["Retry-After"]) == 30
    assert "TRAJLAB_MAX_QUEUED_PER_OWNER" in r.json()["detail"]


def test_body_over_the_cap_is_413(stack):
    client, _, keys = stack
    body = json.dumps({"kind": "intercept", "label": "x" * 200_000}).encode()
    r = client.post("/v1/jobs", content=body, headers={**bearer(keys["alice"]), "Content-Type": "application/json"})
    assert r.status_code == 413


def test_lambert_cap_is_checked_before_the_body_is_parsed(stack):
    client, _, keys = stack
    # 11 problems and then garbage: a parsed body would be a JSON error; the raw count answers first.
    problem = '{"r1_m": [7e6, 0, 0], "r2_m": [0, 7e6, 0], "tof_s": 1000}'
    body = '{"problems": [' + ", ".join([problem] * 11) + ", {not json"
    r = client.post("/v1/lambert", content=body, headers={**bearer(keys["alice"]), "Content-Type": "application/json"})
    assert r.status_code == 422 and r.json()["detail"][0]["type"] == "too_long"
    assert count_lambert_problems(body.encode()) == 11
    ok = client.post("/v1/lambert", json={"problems": [json.loads(problem)] * 10}, headers=bearer(keys["alice"]))
    # without a key: 401 before the body is read, even when it is over the cap
    r = client.post("/v1/lambert", content=body, headers={"Content-Type": "application/json"})
    assert r.status_code == 401
    assert ok.status_code == 200 and len(ok.json()["solutions"]) == 10


def test_lambert_takes_a_body_sized_for_its_problem_cap(tmp_path):
    url = f"sqlite:///{tmp_path / 'l.db'}"
    upgrade(url)
    app = create_app(Settings(database_url=url, broker_url="redis://127.0.0.1:1/0", auth="off",
                              max_body_bytes=1000, lambert_max_problems=100))
    problem = {"r1_m": [7e6, 0, 0], "r2_m": [0, 7e6, 0], "tof_s": 1000}
    with TestClient(app) as client:
        assert client.post("/v1/lambert", json={"problems": [problem] * 50}).status_code == 200  # ~3 kB
        assert client.post("/v1/jobs", json={"kind": "intercept", "label": "x" * 2000}).status_code == 413


@pytest.mark.parametrize("escaped", [r"a\u0000b", r"\ud800", r"x\udc00y", r"\ud83d"])
def test_nul_and_lone_surrogates_are_422(stack, escaped):
    client, _, keys = stack
    body = '{"kind": "intercept", "label": "' + escaped + '"}'
    r = client.post("/v1/jobs", content=body, headers={**bearer(keys["alice"]), "Content-Type": "application/json"})
    assert r.status_code == 422 and r.json()["detail"][0]["type"] == "string_unsafe"


def test_unsafe_text_tells_escapes_from_escaped_backslashes():
    assert unsafe_text(rb'"\\u0000"') is None  # a backslash, then the text u0000
    assert unsafe_text(rb'"\\\u0000"') is not None
    assert unsafe_text(rb'"\ud83d\ude00"') is None  # a valid pair
    assert unsafe_text(rb'"\ud83d\\ude00"') is not None
    assert unsafe_text(b'"caf\xc3\xa9"') is None


def test_a_422_echoes_at_most_a_few_hundred_characters(stack):
    client, _, keys = stack
    r = client.post("/v1/jobs", json={"kind": "intercept", "label": "y" * 50_000}, headers=bearer(keys["alice"]))
    assert r.status_code == 422 and len(r.content) < 2000


def test_a_500_shows_a_request_id_and_nothing_else(stack):
    client, _, _ = stack
    r = client.get("/boom")
    assert r.status_code == 500
    assert r.json()["request_id"] == r.headers["X-Request-ID"]
    assert "hunter2" not in r.text and "RuntimeError" not in r.text and "10.0.0.5" not in r.text


def test_malformed_job_ids_are_404_without_a_query(stack):
    client, _, keys = stack
    assert client.get("/v1/jobs/%00", headers=bearer(keys["alice"])).status_code == 404


def test_cost_estimates_and_queues():
    s = Settings(database_url="sqlite://", auth="off")
    costs = {name: quota.estimate_cost(PRESETS[name].kind, preset_params(name)) for name in PRESETS}
    assert costs["betts-max-crossrange"] == pytest.approx(200.0)
    assert costs["robust-max-crossrange"] == pytest.approx(10 * 200 * (1 + 10_000 / 1000))
    assert costs["upper-stage-two-corrections"] == pytest.approx(100 * 500 / 5)
    assert costs["upper-stage-table3"] == pytest.approx(7.0)
    assert costs["long-range-intercept"] == pytest.approx(8080.5 / 0.5 / 100 + 200 * 4)
    queues = {name: quota.queue_for(PRESETS[name].kind, c, s) for name, c in costs.items()}
    assert queues["robust-max-crossrange"] == QUEUE_HEAVY
    assert queues["upper-stage-two-corrections"] == QUEUE_HEAVY  # 10,000 > heavy_cost 5,000
    assert queues["betts-max-crossrange"] == queues["long-range-intercept"] == QUEUE_JOBS
    assert quota.queue_for("robust_reentry", 0.0, s) == QUEUE_HEAVY  # always


def test_cost_budget_admits_one_big_job_alone_but_not_on_top(sqlite_db):
    s = Settings(database_url="sqlite://", auth="off", max_active_cost_per_owner=1000)
    quota.check_quota(sqlite_db, s, owner="dave", cost=5000)  # nothing active: admitted
    jobs.create_job(sqlite_db, kind="reentry", params={"grid": {"intervals": 400, "substeps": 2}},
                    label=None, preset=None, owner="dave")  # 800 units
    quota.check_quota(sqlite_db, s, owner="dave", cost=200)
    with pytest.raises(quota.QuotaExceeded, match="budget"):
        quota.check_quota(sqlite_db, s, owner="dave", cost=201)
    quota.check_quota(sqlite_db, s, owner="erin", cost=1000)  # another owner's budget is untouched
    quota.check_quota(sqlite_db, s, owner=None, cost=1e12)  # auth off: no quota


def test_an_idempotency_key_of_another_owner_is_a_conflict_not_their_job(sqlite_db):
    job, created = jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None,
                                   idempotency_key="k-1", request_hash="h", owner="alice")
    again, created_again = jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None,
                                           idempotency_key="k-1", request_hash="h", owner="alice")
    assert created and not created_again and again.id == job.id
    with pytest.raises(jobs.IdempotencyConflict):
        jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None,
                        idempotency_key="k-1", request_hash="h", owner="bob")
    with sqlite_db.read() as s:  # the conflict stored nothing for bob
        rows = s.execute(select(Job.id, Job.owner).where(Job.idempotency_key == "k-1")).all()
    assert [(r.id, r.owner) for r in rows] == [(job.id, "alice")]
