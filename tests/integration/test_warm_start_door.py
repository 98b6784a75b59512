"""A warm start checked at the door (issue 28 item 1): ``from_job`` must name a succeeded job of the same
kind that the caller may read, else a 422 naming the field and the reason, and nothing is stored."""
from __future__ import annotations

import uuid

import pytest
from fastapi.testclient import TestClient

from app.api import auth
from app.api.main import create_app
from app.runtime.settings import Settings

pytestmark = pytest.mark.integration

IMPULSIVE = {"methods": ["impulsive"], "scan": {"step_s": 20.0}}
# one IPOPT iteration per mesh cannot meet the miss tolerance: the job fails (not_converged) in seconds
FAILING = {"methods": ["finite_thrust"], "finite_thrust": {"max_iterations": 1, "max_refinements": 0}}


def _total(service) -> int:
    return service.client.get("/v1/jobs", params={"limit": 1}).json()["total"]


def _refused(service, kind: str, params: dict, field: str, reason: str, preset: str | None = None) -> None:
    before = _total(service)
    r = service.submit(kind, preset=preset, params=params)
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["message"].startswith(f"params.{field}: "), body["message"]
    assert reason in body["message"], body["message"]
    assert body["detail"][0]["loc"] == ["body", "params", *field.split(".")]
    assert _total(service) == before  # nothing stored


@pytest.fixture(scope="module")
def donors(service):
    ok = service.submit("intercept", preset="long-range-intercept", params=IMPULSIVE).json()["id"]
    bad = service.submit("intercept", preset="long-range-intercept", params=FAILING).json()["id"]
    assert service.wait(ok, timeout=120)["status"] == "succeeded"
    failed = service.wait(bad, timeout=180)
    assert failed["status"] == "failed", failed
    return {"succeeded": ok, "failed": bad}


def test_unknown_job_is_422(service):
    _refused(service, "intercept", {"initial_guess": {"from_job": uuid.uuid4().hex}}, "initial_guess.from_job",
             "does not exist", preset="long-range-intercept")
    _refused(service, "reentry", {"initial_guess": {"from_job": "not-an-id\u00e9"}}, "initial_guess.from_job",
             "does not exist", preset="betts-max-crossrange")


def test_failed_job_is_422(service, donors):
    _refused(service, "intercept", {"initial_guess": {"from_job": donors["failed"]}}, "initial_guess.from_job",
             "is failed; only a succeeded job", preset="long-range-intercept")


def test_other_kind_is_422(service, donors):
    _refused(service, "reentry", {"initial_guess": {"from_job": donors["succeeded"]}}, "initial_guess.from_job",
             "is a intercept job; a warm start needs a reentry job", preset="betts-max-crossrange")


def test_a_usable_job_is_accepted(service, donors):
    r = service.submit("intercept", preset="long-range-intercept",
                       params={**IMPULSIVE, "initial_guess": {"from_job": donors["succeeded"]}})
    assert r.status_code == 202, r.text
    assert service.wait(r.json()["id"], timeout=120)["status"] == "succeeded"


def test_the_old_spelling_is_accepted_and_stored_as_the_new_one(service, donors):
    """intercept's finite_thrust.from_job (deprecated in OpenAPI) still works: moved to initial_guess.from_job
    before validation, so the stored params and the door's 422 name the new field."""
    r = service.submit("intercept", preset="long-range-intercept",
                       params={**IMPULSIVE, "finite_thrust": {"from_job": donors["succeeded"]}})
    assert r.status_code == 202, r.text
    stored = r.json()["params"]
    assert stored["initial_guess"]["from_job"] == donors["succeeded"] and "from_job" not in stored["finite_thrust"]
    assert service.wait(r.json()["id"], timeout=120)["status"] == "succeeded"
    _refused(service, "intercept", {"finite_thrust": {"from_job": donors["failed"]}}, "initial_guess.from_job",
             "is failed; only a succeeded job", preset="long-range-intercept")


def test_a_study_base_is_checked_too(service, donors):
    r = service.client.post("/v1/studies", json={
        "kind": "intercept", "preset": "long-range-intercept", "mode": "independent",
        "params": {**IMPULSIVE, "initial_guess": {"from_job": donors["failed"]}},
        "sweeps": [{"path": "intercept_time_s", "values": [8000.0, 8100.0]}]})
    assert r.status_code == 422, r.text
    assert "params.initial_guess.from_job: job" in r.json()["message"]


def test_other_owner_reads_as_unknown(service, donors):
    """With keys: bob's succeeded job is no warm start for alice (the same words as an unknown job),
    and is one for bob (the jobs run on the shared worker: same database and broker)."""
    s = service.client.app.state.settings
    app = create_app(Settings(database_url=s.database_url, broker_url=s.broker_url, auth="required"))
    with TestClient(app) as client:
        tag = uuid.uuid4().hex[:6]
        keys = {who: auth.create_key(app.state.db, name=f"warm-{who}-{tag}", owner=f"{who}-{tag}")[1]
                for who in ("alice", "bob")}
        h = {who: {"Authorization": f"Bearer {k}"} for who, k in keys.items()}
        bobs = client.post("/v1/jobs", headers=h["bob"],
                           json={"kind": "intercept", "preset": "long-range-intercept", "params": IMPULSIVE})
        assert bobs.status_code == 202, bobs.text
        assert service.wait(bobs.json()["id"], timeout=120)["status"] == "succeeded"
        body = {"kind": "intercept", "preset": "long-range-intercept",
                "params": {**IMPULSIVE, "initial_guess": {"from_job": bobs.json()["id"]}}}
        before = client.get("/v1/jobs", headers=h["alice"]).json()["total"]
        r = client.post("/v1/jobs", headers=h["alice"], json=body)
        assert r.status_code == 422, r.text
        assert r.json()["message"] == f"params.initial_guess.from_job: job {bobs.json()['id']} does not exist"
        assert client.get("/v1/jobs", headers=h["alice"]).json()["total"] == before
        assert client.post("/v1/jobs", headers=h["bob"], json=body).status_code == 202
        app.state.db.dispose()
