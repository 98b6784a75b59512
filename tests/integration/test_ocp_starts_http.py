"""Several starts of an ``ocp`` job through the whole service (issue 35 item 3): HTTP submit, the starts fanned
out as ``trajlab.piece`` messages to a real worker over real Redis, the result stored in PostgreSQL; one start
that fails (its guess flies where an expression is undefined) does not fail the job."""
import pytest

from tests.unit.test_ocp_starts import ROOT

pytestmark = pytest.mark.integration


def test_one_failing_start_does_not_fail_the_job(service):
    resp = service.submit("ocp", params={**ROOT, "search": {"starts": 4}}, label="ocp four starts")
    assert resp.status_code == 202, resp.text
    job = service.wait(resp.json()["id"], timeout=300)
    assert job["status"] == "succeeded", job
    assert job["progress"] == 1.0
    result = service.result(job["id"])
    search = result["search"]
    assert search["starts"] == 4 and search["succeeded"] == 3
    assert [e["start"] for e in search["each"]] == [0, 1, 2, 3]
    failed = [e for e in search["each"] if e["status"] == "failed"]
    assert len(failed) == 1 and failed[0]["code"] == "numerical_overflow", search["each"]
    # every start was computed by a process of the service (the job's own or another worker's) and says which
    assert all(e["by"] for e in search["each"]), search["each"]
    # the worker's other pool process took some while the job's own built its first NLP (~17 s)
    assert any(not e["by"].startswith("job@") for e in search["each"]), search["each"]
    assert len(search["distinct_optima"]) == 1 and search["distinct_optima"][0]["count"] == 3
    best = search["each"][search["best_start"]]
    assert best["status"] == "succeeded" and result["objective"]["value"] == best["objective"]


def test_too_many_starts_are_a_422_naming_the_setting(service):
    resp = service.submit("ocp", params={**ROOT, "search": {"starts": 1000}})
    assert resp.status_code == 422, resp.text
    assert "TRAJLAB_OCP_MAX_STARTS" in resp.text and "search" in resp.text
