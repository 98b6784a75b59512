"""reentry through HTTP, a real worker, Redis and PostgreSQL."""
import pytest

pytestmark = pytest.mark.integration


def test_betts_max_crossrange_and_warm_start(service):
    r = service.submit("reentry", preset="betts-max-crossrange")
    assert r.status_code == 202, r.text
    job = service.wait(r.json()["id"], timeout=180)
    assert job["status"] == "succeeded", job
    res = service.result(job["id"])
    assert res["solver"]["status"] == "Solve_Succeeded"
    assert res["final"]["latitude_deg"] == pytest.approx(34.1412, abs=1e-3)
    assert res["tf_s"] == pytest.approx(2008.59, abs=0.5)
    assert job["params"]["grid"]["intervals"] == 100

    r2 = service.submit("reentry", preset="betts-max-crossrange",
                        params={"grid": {"intervals": 60}, "initial_guess": {"from_job": job["id"]}})
    assert r2.status_code == 202, r2.text
    job2 = service.wait(r2.json()["id"], timeout=180)
    assert job2["status"] == "succeeded", job2
    res2 = service.result(job2["id"])
    assert res2["final"]["latitude_deg"] == pytest.approx(34.1412, abs=2e-3)
    # the warm solve itself; a terminal refinement round may follow at 60 intervals (issue 25)
    assert res2["solver"]["stages"][0]["iterations"] <= 15
    assert res2["verification"]["terminal_held"] is True


def test_case4_fails_infeasible(service):
    r = service.submit("reentry", preset="shuttle-min-heat-load-terminal")
    assert r.status_code == 202, r.text
    job = service.wait(r.json()["id"], timeout=180)
    assert job["status"] == "failed", job
    assert job["error"]["code"] == "infeasible"
    assert "Infeasible_Problem_Detected" in job["error"]["message"]
    assert "latitude" in job["error"]["message"]


def test_bad_reentry_params_are_422(service):
    r = service.submit("reentry", params={"bounds": {"alpha_deg": [10.0, 0.0]}})
    assert r.status_code == 422
    assert "alpha_deg" in r.text
