"""The ocp kind through the whole service: HTTP submit, real worker, stored result, plots and files;
an infeasible problem fails with its diagnostic stored; a warm start from a job that cannot give one
fails cleanly (never ``internal``)."""
import pytest

from app.kinds import PRESETS
from solvers.ocp.cases import PRESETS as CASES

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def brachistochrone(service):
    resp = service.submit("ocp", preset="brachistochrone", label="ocp brachistochrone")
    assert resp.status_code == 202, resp.text
    done = service.wait(resp.json()["id"], timeout=180)
    assert done["status"] == "succeeded", done
    return done


def test_brachistochrone_preset_reaches_the_published_minimum_time(service, brachistochrone):
    assert PRESETS["brachistochrone"].kind == "ocp"
    job = brachistochrone
    assert job["progress"] == 1.0
    assert job["params"]["transcription"]["method"] == "multiple_shooting"   # resolved, defaults filled in
    result = service.result(job["id"])
    case = CASES["brachistochrone"]
    assert result["objective"]["sense"] == "minimize"
    assert result["objective"]["value"] == pytest.approx(1.8016, abs=case["tolerance"])
    assert result["objective"]["value"] == pytest.approx(case["optimum"], abs=case["tolerance"])
    assert result["tf"] == pytest.approx(result["objective"]["value"], rel=1e-9)
    assert result["solver"]["status"] == "Solve_Succeeded" and result["solver"]["iterations"] > 0
    assert result["final"]["x"] == pytest.approx(10.0, abs=1e-6)
    assert result["final"]["y"] == pytest.approx(5.0, abs=1e-6)
    tr = result["trajectory"]
    assert {"t", "x", "y", "v", "theta"} <= set(tr)
    assert len({len(v) for v in tr.values()}) == 1 and tr["t"][-1] == pytest.approx(result["tf"])
    ver = result["verification"]
    assert ver["ok"] and ver["limits_held"] is True
    # the re-flown controls land on the solution to the method's accuracy (scaled by each state's scale)
    assert ver["max_state_difference_scaled_overall"] < 1e-4 and ver["agrees"] is True
    numbers = service.client.get(f"/console/jobs/{job['id']}/numbers").json()
    assert numbers["objective"] == result["objective"]["value"] and numbers["limits_held"] is True
    assert numbers["verification_agrees"] is True


def test_plots_tables_and_report_are_served(service, brachistochrone):
    job_id = brachistochrone["id"]
    index = service.client.get(f"/v1/jobs/{job_id}/plots")
    assert index.status_code == 200, index.text
    index = index.json()
    names = {p["name"] for p in index["plots"]}
    assert {"t-x", "t-y", "t-v", "t-theta"} <= names
    for pair in brachistochrone["params"]["plots"]:
        assert "-".join(pair) in names
    png = service.client.get(index["plots"][0]["png"])
    assert png.status_code == 200 and png.headers["content-type"] == "image/png" and png.content[:4] == b"\x89PNG"
    svg = service.client.get(index["plots"][-1]["svg"])
    assert svg.status_code == 200 and b"<svg" in svg.content
    csv = service.client.get(f"/v1/jobs/{job_id}/result.csv", params={"table": "trajectory"})
    assert csv.status_code == 200 and csv.text.splitlines()[0].startswith("t,x,y,v,theta")
    report = service.client.get(index["report"])
    assert report.status_code == 200 and "ocp job" in report.text and "<svg" in report.text


def test_an_infeasible_problem_fails_as_infeasible_with_its_diagnostic_stored(service):
    # 10 m across and 5 m down in 0.3 s: the bead cannot get there
    resp = service.submit("ocp", preset="brachistochrone",
                          params={"time": {"final": 0.3, "final_lower": None, "final_upper": None,
                                           "final_guess": None}})
    assert resp.status_code == 202, resp.text
    done = service.wait(resp.json()["id"], timeout=180)
    assert done["status"] == "failed", done
    assert done["error"]["code"] == "infeasible", done["error"]
    assert "Infeasible" in done["error"]["message"]
    assert done["error"]["details"]["iterations"] > 0
    body = service.client.get(f"/v1/jobs/{done['id']}/result")
    assert body.status_code == 409
    partial = body.json()["partial_result"]
    assert partial["solver"]["outcome"] == "infeasible" and partial["trajectory"]["t"]


@pytest.mark.parametrize("from_job", ["unknown", "failed"])
def test_warm_start_from_an_unknown_or_failed_job_is_a_clean_failure(service, from_job):
    if from_job == "failed":
        bad = service.submit("ocp", preset="brachistochrone", params={
            "boundary": [{"expr": "final(x)", "lower": 12.0}]})   # final x is fixed at 10: infeasible
        assert bad.status_code == 202, bad.text
        failed = service.wait(bad.json()["id"], timeout=180)
        assert failed["status"] == "failed"
        from_job = failed["id"]
    else:
        from_job = "00000000-0000-0000-0000-000000000000"
    resp = service.submit("ocp", preset="brachistochrone", params={"initial_guess": {"from_job": from_job}})
    assert resp.status_code in (202, 422), resp.text
    if resp.status_code == 422:
        assert "initial_guess.from_job" in resp.json()["message"]
        return
    done = service.wait(resp.json()["id"], timeout=120)
    assert done["status"] == "failed"
    assert done["error"]["code"] == "invalid_input", done["error"]
    assert "initial_guess.from_job" in done["error"]["message"] and from_job in done["error"]["message"]


def test_warm_start_from_a_solved_job(service, brachistochrone):
    resp = service.submit("ocp", preset="brachistochrone",
                          params={"initial_guess": {"from_job": brachistochrone["id"]}, "transcription": {"intervals": 60}})
    assert resp.status_code == 202, resp.text
    done = service.wait(resp.json()["id"], timeout=180)
    assert done["status"] == "succeeded", done
    result = service.result(done["id"])
    assert result["warm_start"] == brachistochrone["id"]
    assert result["objective"]["value"] == pytest.approx(1.8016, abs=CASES["brachistochrone"]["tolerance"])
    # the console overlays the two (the first pair the problem asked for, else its first state against time)
    png = service.client.get("/console/compare.png", params={"ids": f"{brachistochrone['id']},{done['id']}"})
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"


def test_a_malformed_problem_is_a_422_naming_the_field_and_nothing_is_stored(service):
    before = service.client.get("/v1/jobs", params={"kind": "ocp", "limit": 1}).json()["total"]
    resp = service.submit("ocp", preset="brachistochrone", params={"dynamics": {"x": "vv*sin(theta)"}})
    assert resp.status_code == 422
    body = resp.json()
    assert body["detail"][0]["loc"] == ["body", "params", "dynamics", "x"]
    assert "did you mean 'v'?" in body["message"]
    assert service.client.get("/v1/jobs", params={"kind": "ocp", "limit": 1}).json()["total"] == before
