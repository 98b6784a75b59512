"""The kinds' typed result models against real results: every preset's result (the compact default
body and the full ``?include=`` body) validates against its kind's model with undeclared fields
FORBIDDEN, so a field added to a result without its model fails here; and ``GET /result`` serves
the body unchanged through the models.

When this test fails after a change to a kind's result: declare the new field in the kind's model
(``app/kinds/*result_model*.py``), optional (``= Field(None, ...)``) unless every stored result has
it, with a description naming its unit.
"""
from __future__ import annotations

import json
import math

import pytest
from pydantic import BaseModel, ValidationError

from app.kinds import KINDS, PRESETS
from app.results.compact import compact
from app.api.result_body import result_json, result_models
from tests.preset_results import solve_preset

INCLUDES = (set(), {"scan", "samples"})
# Extra cases that switch optional blocks on: a midcourse dispersion (mean, percentile), impulsive only.
EXTRA_CASES = {
    "upper-stage-table3": {"dispersion": {"samples": 20, "percentile": 95.0, "seed": 3, "statistic": "mean"}},
    "upper-stage-two-corrections": {"population": 12, "generations": 4,
                                    "dispersion": {"samples": 10, "statistic": "percentile"}},
    "long-range-intercept": {"methods": ["impulsive"]},
}


def undeclared(value, path: str = "") -> list[str]:
    """Paths of every field a validated model kept as an extra (``extra="allow"``): not declared."""
    out: list[str] = []
    if isinstance(value, BaseModel):
        out += [f"{path}.{k}" for k in (value.model_extra or {})]
        for name in type(value).model_fields:
            out += undeclared(getattr(value, name), f"{path}.{name}")
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            if not isinstance(v, (BaseModel, list, tuple, dict)):
                break  # a list of numbers
            out += undeclared(v, f"{path}[{i}]")
    elif isinstance(value, dict):
        for k, v in value.items():
            out += undeclared(v, f"{path}.{k}")
    return out


def check_result(kind: str, result: dict) -> None:
    """Both bodies validate with no undeclared field, and pydantic-core writes them unchanged."""
    model = KINDS[kind].result_model
    for include in INCLUDES:
        body = compact(kind, result, include)
        typed = model.model_validate(body)
        assert undeclared(typed) == [], f"{kind} result fields without a model (include={include})"
        assert json.loads(result_json(kind, body)) == json.loads(json.dumps(body))


# Presets whose solve takes seconds run in `make test` only (`slow`); `make check` still validates every
# kind's model on its quick presets (bryson-denham-robust for a robust ocp, betts-max-crossrange for a reentry).
LONG_SOLVES = {"betts-shuttle-robust-ocp", "betts-shuttle-heat-limit-ocp", "betts-shuttle-ocp",
               "rocket-ascent-q-limit-robust", "rocket-ascent-q-limit", "shuttle-min-heat-load"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow)
                                  if p.kind == "robust_reentry" or n in LONG_SOLVES else n
                                  for n, p in PRESETS.items()])
def test_every_presets_result_validates_with_undeclared_fields_forbidden(name):
    kind, _, outcome = solve_preset(name)
    if outcome.status != "succeeded":  # paper 000 case 4 is infeasible by design: no result to serve
        assert name == "shuttle-min-heat-load-terminal" and outcome.error["code"] == "infeasible"
        return
    check_result(kind, outcome.result)


@pytest.mark.parametrize("name", sorted(EXTRA_CASES))
def test_optional_blocks_validate_too(name):
    kind, _, outcome = solve_preset(name, EXTRA_CASES[name])
    assert outcome.status == "succeeded", outcome.error
    check_result(kind, outcome.result)
    if kind == "midcourse":
        point = KINDS[kind].result_model.model_validate(outcome.result).pareto_front[0]
        assert point.mean is not None and point.percentile is not None
    else:
        assert outcome.result["finite_thrust"] is None and outcome.result["impulsive"]["scan"]


def test_an_undeclared_field_and_a_nan_are_caught():
    _, _, outcome = solve_preset("upper-stage-table3")
    model = KINDS["midcourse"].result_model
    drifted = json.loads(json.dumps(outcome.result))
    drifted["pareto_front"][1]["new_quantity_m"] = 1.0
    drifted["settings"]["new_setting"] = True
    assert undeclared(model.model_validate(drifted)) == [".pareto_front[1].new_quantity_m", ".settings.new_setting"]
    nan = json.loads(json.dumps(outcome.result))
    nan["hypervolume"] = math.nan  # the policy is null, never NaN
    with pytest.raises(ValidationError):
        model.model_validate(nan)
    nan["hypervolume"] = None
    assert model.model_validate(nan).hypervolume is None


def test_every_kind_declares_a_documented_model_in_the_openapi_document():
    from app.api.main import create_app

    assert set(result_models()) == set(KINDS)
    assert list(result_models())[:2] == ["robust_reentry", "reentry"]  # generated clients try them in order

    def walk(model: type[BaseModel], seen: set) -> None:
        if model in seen:
            return
        seen.add(model)
        for name, field in model.model_fields.items():
            assert field.description, f"{model.__name__}.{name} has no description"
            for arg in _models_in(field.annotation):
                walk(arg, seen)

    seen: set = set()
    for model in result_models().values():
        walk(model, seen)
    doc = create_app().openapi()
    schema = doc["paths"]["/v1/jobs/{job_id}/result"]["get"]["responses"]["200"]["content"]["application/json"]["schema"]
    assert sorted(ref["$ref"].rsplit("/", 1)[1] for ref in schema["anyOf"]) == sorted(
        m.__name__ for m in result_models().values())
    components = doc["components"]["schemas"]
    assert components["ReentryResultTrajectory"]["properties"]["heat_rate_w_m2"]["description"].startswith(
        "Stagnation-point heating rate (W/m^2)")
    assert len(seen) == len({m.__name__ for m in seen}) and all(m.__name__ in components for m in seen)


def _models_in(annotation) -> list[type[BaseModel]]:
    import typing

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for a in typing.get_args(annotation) for m in _models_in(a)]


def test_get_result_serves_the_stored_body_through_the_model(tmp_path):
    from fastapi.testclient import TestClient

    from app.service import jobs
    from app.runtime.db import get_database
    from app.api.main import create_app
    from app.runtime.migrate import upgrade
    from app.runtime.settings import Settings

    url = f"sqlite:///{tmp_path / 'r.db'}"
    upgrade(url)
    db = get_database(url)
    kind, params, outcome = solve_preset("long-range-intercept")
    stale = {**outcome.result, "comparison": "not a list"}  # a stored result the model rejects
    ids = []
    for result in (outcome.result, stale):
        job, _ = jobs.create_job(db, kind=kind, params=params, label=None, preset=None)
        claim = jobs.claim(db, job.id, job.attempts, worker="t", max_attempts=3, stale_after_s=60)
        assert jobs.finish(db, job.id, claim.attempt, status="succeeded", result=result, error=None, message="done")
        ids.append(job.id)
    db.dispose()
    with TestClient(create_app(Settings(database_url=url, broker_url="redis://127.0.0.1:1/0"))) as client:
        for include, want in (([], compact(kind, outcome.result, set())), (["scan"], outcome.result)):
            r = client.get(f"/v1/jobs/{ids[0]}/result", params={"include": include})
            assert r.status_code == 200 and r.headers["content-type"] == "application/json"
            assert r.json() == json.loads(json.dumps(want))
        r = client.get(f"/v1/jobs/{ids[1]}/result", params={"include": ["scan"]})
        assert r.status_code == 200 and r.json()["comparison"] == "not a list"  # served as stored, never a 500
