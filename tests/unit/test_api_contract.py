"""The HTTP contract that needs no worker: kinds, presets, OpenAPI, validation messages."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from app.kinds import KIND_NAMES, KINDS, PRESETS
from app.api.main import create_app
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings
from app.service.broker import longest_hard_time_limit_s, time_limit_s

FIXED_PRESETS = {
    "betts-max-crossrange": "reentry",
    "betts-max-crossrange-heat-limited": "reentry",
    "shuttle-max-downrange": "reentry",
    "shuttle-max-crossrange": "reentry",
    "shuttle-min-heat-load": "reentry",
    "shuttle-min-heat-load-terminal": "reentry",
    "robust-max-crossrange": "robust_reentry",
    "upper-stage-two-corrections": "midcourse",
    "long-range-intercept": "intercept",
}


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    url = f"sqlite:///{tmp_path_factory.mktemp('api') / 'api.db'}"
    upgrade(url)
    # The broker is never contacted by these tests (nothing is submitted successfully).
    with TestClient(create_app(Settings(database_url=url, broker_url="redis://127.0.0.1:1/0"))) as c:
        yield c


def test_every_kind_of_the_contract_is_registered():
    assert set(KINDS) == set(KIND_NAMES)


def test_fixed_presets_exist_with_their_kind(client):
    listed = {p["name"]: p for p in client.get("/v1/presets").json()}
    for name, kind in FIXED_PRESETS.items():
        assert name in listed, name
        assert listed[name]["kind"] == kind
        assert len(listed[name]["description"]) > 40
        one = client.get(f"/v1/presets/{name}")
        assert one.status_code == 200 and one.json()["params"] == listed[name]["params"]
    assert client.get("/v1/presets/nope").status_code == 404


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_preset_params_are_valid_and_resolved(name):
    spec = KINDS[PRESETS[name].kind]
    resolved = spec.params_model.model_validate(PRESETS[name].params).model_dump(mode="json")
    assert spec.params_model.model_validate(resolved).model_dump(mode="json") == resolved


def test_openapi_documents_every_kind_and_route(client):
    doc = client.get("/openapi.json").json()
    for path in ("/v1/jobs", "/v1/jobs/{job_id}", "/v1/jobs/{job_id}/result", "/v1/jobs/{job_id}/cancel",
                 "/v1/presets", "/v1/presets/{name}", "/v1/lambert", "/healthz", "/readyz"):
        assert path in doc["paths"], path
    schemas = doc["components"]["schemas"]
    for kind in KIND_NAMES:
        title = "".join(p.capitalize() for p in kind.split("_")) + "Submission"
        assert title in schemas, title
    assert client.get("/docs").status_code == 200


@pytest.mark.parametrize("body, field", [
    ({"kind": "reentry", "params": {"grid": {"intervals": 10**6}}}, "intervals"),
    ({"kind": "reentry", "params": {"grid": {"intervals": -3}}}, "intervals"),
    ({"kind": "midcourse", "params": {"population": 1}}, "population"),
    ({"kind": "intercept", "params": {"interceptor": {"isp_s": 0}}}, "isp_s"),
    ({"kind": "robust_reentry", "params": {"monte_carlo": {"samples": -1}}}, "samples"),
    ({"kind": "reentry", "params": {"bogus": 1}}, "bogus"),
])
def test_bad_input_is_422_naming_the_field(client, body, field):
    before = client.get("/v1/jobs").json()["total"]
    r = client.post("/v1/jobs", json=body)
    assert r.status_code == 422, r.text
    assert field in r.json()["message"]
    assert client.get("/v1/jobs").json()["total"] == before


def test_readyz_names_the_unreachable_broker(client):
    r = client.get("/readyz")
    assert r.status_code == 503
    # no address or driver message: the broker's address stays in the log (issue 11)
    body = r.json()
    assert (body["status"], body["database"], body["broker"]) == ("not ready", "up", "down")
    # nothing ever held the recovery lease of this fresh database (app.service.lease)
    assert body["recovery"].startswith("never ran")


def test_metrics_without_a_broker_are_the_database_families(client):
    """A scrape while the broker is unreachable is a 200 without the broker's families (issue 36: it was a
    500 after waiting out the Redis timeouts)."""
    r = client.get("/metrics")
    assert r.status_code == 200, r.text
    assert "trajlab_jobs_submitted" in r.text and "trajlab_queue_depth" not in r.text


def test_list_offset_beyond_64_bits_is_422_not_500(client):
    """Found by schemathesis: an OFFSET past 2**63 overflowed the database driver."""
    assert client.get("/v1/jobs", params={"offset": 2**63}).status_code == 422
    r = client.get("/v1/jobs", params={"offset": 2**62})
    assert r.status_code == 200 and r.json()["items"] == []


def test_time_limits_come_from_each_kind_and_the_env_overrides_them(monkeypatch):
    for name in list(__import__("os").environ):
        if name.startswith("TRAJLAB_TIME_LIMIT_"):
            monkeypatch.delenv(name)
    s = Settings()
    assert {k: time_limit_s(s, k) for k in KIND_NAMES} == {k: KINDS[k].time_limit_s for k in KIND_NAMES}
    assert time_limit_s(s, "robust_reentry") == 1800.0 and time_limit_s(s, "midcourse") == 900.0
    assert longest_hard_time_limit_s(s) == 1800.0 + s.hard_time_limit_margin_s
    monkeypatch.setenv("TRAJLAB_TIME_LIMIT_MIDCOURSE_S", "5")
    monkeypatch.setenv("TRAJLAB_TIME_LIMIT_ROBUST_REENTRY_S", "4000")
    s = Settings()
    assert time_limit_s(s, "midcourse") == 5.0 and time_limit_s(s, "intercept") == KINDS["intercept"].time_limit_s
    assert longest_hard_time_limit_s(s) == 4000.0 + s.hard_time_limit_margin_s
    monkeypatch.setenv("TRAJLAB_TIME_LIMIT_MIDCOURSE_S", "-1")
    with pytest.raises(ValueError):
        Settings()


# Titles still shared while a rename is under way. Empty it, never add to it.
PENDING_SCHEMA_RENAMES: set[str] = set()


def test_every_schema_has_a_unique_meaningful_title():
    # pydantic falls back to module-qualified names (app__kinds__x__Params) when two models share a
    # name: each model of the app has one name of its own instead.
    schemas = create_app(Settings(database_url="sqlite://", broker_url="redis://127.0.0.1:1/0")).openapi()[
        "components"]["schemas"]
    titles = [s.get("title", name) for name, s in schemas.items()]
    shared = sorted({t for t in titles if titles.count(t) > 1} - PENDING_SCHEMA_RENAMES)
    assert shared == []
    assert [name for name in schemas if "__" in name and name.split("__")[-1] not in PENDING_SCHEMA_RENAMES] == []
    for kind in ("intercept", "midcourse"):
        assert KINDS[kind].params_model.__name__ == f"{kind.capitalize()}Params"


def test_operation_ids_are_the_route_names_and_unique():
    from collections import Counter

    from app.api.main import create_app

    doc = create_app().openapi()
    ids = [op["operationId"] for path in doc["paths"].values() for op in path.values()
           if isinstance(op, dict) and "operationId" in op]
    assert {"submit_job", "list_jobs", "get_job", "get_result", "cancel_job", "solve_lambert", "get_plot"} <= set(ids)
    assert not [i for i, c in Counter(ids).items() if c > 1]
    assert all("_v1_" not in i for i in ids)  # not FastAPI's generated get_result_v1_jobs_job_id_result_get
