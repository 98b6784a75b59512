"""Headline numbers (app.kinds.headlines) of every kind from real preset results, and failed jobs
explained (app.kinds.failures), through the console's summary routes (SQLite, TestClient)."""
from __future__ import annotations

import re

import pytest

from app.kinds.failures import ADVICE, WHAT, as_lines, explain
from app.service.summary import headlines
from tests.preset_results import solve_preset


def _texts(name: str) -> tuple[list[dict], dict]:
    kind, params, outcome = solve_preset(name)
    assert outcome.status == "succeeded", outcome.error
    return headlines(kind, outcome.result, params), outcome.result


def _number(text: str) -> float:
    return float(re.search(r"(-?[\d,]+\.?\d*(?:e[-+]\d+)?)", text).group(1).replace(",", ""))


@pytest.mark.slow
def test_reentry_heat_limited_says_crossrange_and_that_the_limit_held():
    lines, result = _texts("betts-max-crossrange-heat-limited")
    first = lines[0]
    assert first["name"].startswith("crossrange") and first["unit"] == "deg"
    assert first["text"].endswith(" deg") and _number(first["text"].split(")")[1]) == pytest.approx(
        result["objective"]["value"], rel=1e-3)
    heat = next(h for h in lines if h["name"] == "heating limit")
    check = result["verification"]["limits"]["heat_rate_w_m2"]
    assert heat["verdict"] == ("held" if check["held"] else "not held") and heat["good"] is check["held"]
    assert heat["value"] == pytest.approx(100 * check["max"] / check["limit"], rel=1e-6)
    assert heat["text"].startswith("heating limit held: peak ") and "of 794,955 W/m^2" in heat["text"]
    assert any(h["name"] == "terminal conditions" and h["good"] is result["verification"]["terminal_held"]
               for h in lines)


@pytest.mark.slow
def test_robust_reentry_leads_with_the_monte_carlo_kept_share():
    lines, result = _texts("robust-max-crossrange")
    mc = next(h for h in lines if h["name"] == "Monte Carlo heating kept")
    robust = result["monte_carlo"]["robust"]
    assert mc["value"] == pytest.approx(100 * robust["heat_rate_kept_fraction"])
    assert mc["text"].startswith(f"Monte Carlo: heating kept in {100 * robust['heat_rate_kept_fraction']:.2f}% "
                                 f"of {robust['samples']:,} samples")
    assert mc["verdict"] in ("kept", "not kept") and isinstance(mc["good"], bool)
    assert lines[0]["unit"] == "deg" and lines[0]["value"] == result["objective"]["value"]


@pytest.mark.slow
def test_midcourse_front_size_and_best_delta_v():
    lines, result = _texts("upper-stage-two-corrections")
    assert lines[0]["text"] == f"Pareto front {len(result['pareto_front'])} points"
    best = next(h for h in lines if h["name"] == "best delta-v")
    assert best["value"] == min(p["delta_v_mps"] for p in result["pareto_front"]) and best["unit"] == "m/s"


@pytest.mark.slow
def test_intercept_each_method_with_delta_v_and_propellant():
    lines, result = _texts("long-range-intercept")
    for row in result["comparison"]:
        line = next(h for h in lines if h["name"] == f"{row['method']} delta-v")
        assert line["value"] == row["delta_v_mps"] and "propellant" in line["text"] and " kg" in line["text"]


def test_ocp_objective_with_its_sense_expression_and_unit():
    lines, result = _texts("brachistochrone")
    assert lines[0]["name"] == "objective (minimize tf)" and lines[0]["unit"] == "s"
    assert lines[0]["value"] == result["objective"]["value"]
    assert any(h["name"] == "path limits" and h["good"] is True for h in lines)


def test_a_kind_without_a_declaration_falls_back_to_its_key_numbers():
    assert headlines("reentry", None) == []
    lines = headlines("no-such-kind", {"a": 1.5, "b": {"c": 2}})
    assert [h["text"] for h in lines] == ["a 1.5", "b.c 2"]


def test_the_infeasible_preset_is_explained_with_where_and_what_to_try():
    kind, _, outcome = solve_preset("shuttle-min-heat-load-terminal")
    assert outcome.status == "failed" and outcome.error["code"] == "infeasible"
    explained = explain(outcome.error, outcome.result)
    assert explained["what"] == WHAT["infeasible"] and explained["advice"] == ADVICE["infeasible"]
    # "worst matching defect ... at interval 99" is placed in time on the stored last iterate
    j = int(re.search(r"at interval (\d+)", outcome.error["message"]).group(1))
    assert f"t = {outcome.result['trajectory']['t_s'][j]:.1f} s" in explained["where"]
    text = "\n".join(as_lines(explained))
    assert "latitude" in text and "What to try:" in text and "/guide/failures/" in text


def test_every_api_error_code_has_a_meaning_and_advice():
    from typing import get_args

    from app.api.schemas import ErrorCode

    assert set(get_args(ErrorCode)) <= set(WHAT) and set(WHAT) == set(ADVICE)


@pytest.mark.slow
def test_the_console_summary_of_a_succeeded_and_a_failed_job(tmp_path):
    from fastapi.testclient import TestClient

    from app.api.main import create_app
    from app.runtime.db import get_database
    from app.runtime.migrate import upgrade
    from app.runtime.settings import Settings
    from app.service import jobs

    url = f"sqlite:///{tmp_path / 'h.db'}"
    upgrade(url)
    db = get_database(url)
    ids = {}
    for name in ("betts-max-crossrange-heat-limited", "shuttle-min-heat-load-terminal"):
        kind, params, outcome = solve_preset(name)
        job, _ = jobs.create_job(db, kind=kind, params=params, label=name, preset=name)
        claim = jobs.claim(db, job.id, job.attempts, worker="t", max_attempts=3, stale_after_s=60)
        assert jobs.finish(db, job.id, claim.attempt, status=outcome.status, result=outcome.result,
                           error=outcome.error, message="done")
        ids[outcome.status] = job.id
    db.dispose()
    with TestClient(create_app(Settings(database_url=url, broker_url="redis://127.0.0.1:1/0"))) as client:
        ok = client.get(f"/console/jobs/{ids['succeeded']}/summary").json()
        assert ok["preset"] == "betts-max-crossrange-heat-limited" and ok["failure"] is None
        assert ok["headlines"][0]["unit"] == "deg"
        report = client.get(f"/v1/jobs/{ids['succeeded']}/report.html").text
        assert all(h["text"] in report for h in ok["headlines"])
        listed = client.get("/console/headlines", params={"ids": f"{ids['succeeded']},{ids['failed']},{'0' * 32}"})
        assert listed.json() == {ids["succeeded"]: ok["headlines"][0]["text"]}
        bad = client.get(f"/console/jobs/{ids['failed']}/summary").json()
        assert bad["headlines"] == [] and bad["failure"]["code"] == "infeasible" and bad["failure"]["where"]
        assert bad["last_iterate_plots"], bad
        png = client.get(bad["last_iterate_plots"][0]["png"])
        assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
        assert client.get(f"/console/jobs/{ids['succeeded']}/last-iterate/x.png").status_code == 409
        assert client.get(f"/console/jobs/{'0' * 32}/summary").status_code == 404
