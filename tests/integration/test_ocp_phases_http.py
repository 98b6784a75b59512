"""Several ocp phases through the whole service (issue 26): HTTP submit of a staged problem, real
worker, stored result with one block per phase and the stage drop honoured, plots and CSV of the
phases, a warm start from the stored phases, and the 422s of phases before anything is stored."""
import copy
import time

import pytest

from solvers.ocp.cases import PRESETS as CASES

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def staged(service):
    resp = service.submit("ocp", preset="two-stage-ascent", label="ocp two stages")
    assert resp.status_code == 202, resp.text
    done = service.wait(resp.json()["id"], timeout=240)
    assert done["status"] == "succeeded", done
    return done


def test_a_staged_job_stores_each_phase_and_honours_the_drop(service, staged):
    result = service.result(staged["id"])
    case = CASES["two-stage-ascent"]
    assert result["objective"]["sense"] == "maximize"
    assert result["objective"]["value"] == pytest.approx(case["optimum"], abs=case["tolerance"])
    assert [p["name"] for p in result["phases"]] == ["stage1", "stage2", "coast"]
    s1, s2, coast = result["phases"]
    assert s2["initial"]["m"] - s1["final"]["m"] == pytest.approx(-100.0, abs=1e-9)
    assert s2["t0"] == pytest.approx(s1["tf"], rel=1e-9) and coast["t0"] == pytest.approx(s2["tf"], rel=1e-9)
    assert result["t0"] == 0.0 and result["tf"] == pytest.approx(coast["tf"])
    assert result["verification"]["links"]["stage1_drop"]["value"] == pytest.approx(0.0, abs=1e-9)
    for p in result["phases"]:
        assert p["verification"]["ok"] and p["verification"]["agrees"]
        assert p["trajectory"]["t"][0] == pytest.approx(p["t0"]) and p["trajectory"]["t"][-1] == pytest.approx(p["tf"])
    assert "trajectory" not in result or result["trajectory"] is None
    numbers = service.client.get(f"/console/jobs/{staged['id']}/numbers").json()
    assert numbers["objective"] == result["objective"]["value"]


def test_plots_and_csv_show_the_phases(service, staged):
    index = service.client.get(f"/v1/jobs/{staged['id']}/plots").json()
    names = {p["name"] for p in index["plots"]}
    assert {"t-h", "t-v", "t-m", "t-T"} <= names
    svg = service.client.get(next(p["svg"] for p in index["plots"] if p["name"] == "t-v"))
    assert svg.status_code == 200 and b"<svg" in svg.content and b"stage2" in svg.content
    csv = service.client.get(f"/v1/jobs/{staged['id']}/result.csv", params={"table": "trajectory"})
    assert csv.status_code == 200
    lines = csv.text.splitlines()
    assert lines[0].startswith("phase,t,h,v,m")
    assert {ln.split(",")[0] for ln in lines[1:]} == {"stage1", "stage2", "coast"}


def test_a_warm_start_from_the_stored_phases(service, staged):
    resp = service.submit("ocp", preset="two-stage-ascent", params={"initial_guess": {"from_job": staged["id"]}})
    assert resp.status_code == 202, resp.text
    done = service.wait(resp.json()["id"], timeout=240)
    assert done["status"] == "succeeded", done
    result = service.result(done["id"])
    assert result["warm_start"] == staged["id"]
    assert result["objective"]["value"] == pytest.approx(CASES["two-stage-ascent"]["optimum"], abs=0.5)
    # a single phase cannot start from several, nor other phases: 422s at the door naming the field and why
    resp = service.submit("ocp", preset="brachistochrone", params={"initial_guess": {"from_job": staged["id"]}})
    assert resp.status_code == 422, resp.text
    assert resp.json()["detail"][0]["loc"] == ["body", "params", "initial_guess", "from_job"]
    assert "multi-phase" in resp.json()["message"]
    resp = service.submit("ocp", preset="goddard-three-phases", params={"initial_guess": {"from_job": staged["id"]}})
    assert resp.status_code == 422 and "phase names must be the same" in resp.json()["message"], resp.text


def test_bad_phases_are_422s_naming_the_field_and_nothing_is_stored(service):
    before = service.client.get("/v1/jobs", params={"kind": "ocp", "limit": 1}).json()["total"]
    params = copy.deepcopy(CASES["two-stage-ascent"]["params"])
    params["phases"][2]["name"] = "stage1"
    resp = service.submit("ocp", params=params)
    assert resp.status_code == 422
    assert resp.json()["detail"][0]["loc"] == ["body", "params", "phases", 2, "name"]
    params = copy.deepcopy(CASES["two-stage-ascent"]["params"])
    params["links"][0]["expr"] = 'initial(m, "stage2") - final(m, "stage_1") + dry1'
    resp = service.submit("ocp", params=params)
    assert resp.status_code == 422 and "did you mean 'stage1'" in resp.json()["message"]
    assert resp.json()["detail"][0]["loc"] == ["body", "params", "links", 0, "expr"]
    assert service.client.get("/v1/jobs", params={"kind": "ocp", "limit": 1}).json()["total"] == before


def test_the_console_compares_two_staged_jobs(service, staged):
    resp = service.submit("ocp", preset="two-stage-ascent", params={"constants": {"dry1": 120.0}})
    assert resp.status_code == 202, resp.text
    other = service.wait(resp.json()["id"], timeout=240)
    assert other["status"] == "succeeded", other
    # a heavier structure dropped: a lower apogee
    assert service.result(other["id"])["objective"]["value"] < service.result(staged["id"])["objective"]["value"]
    png = service.client.get("/console/compare.png", params={"ids": f"{staged['id']},{other['id']}"})
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"


def test_a_study_sweeps_a_phase_bound_by_the_phase_name(service):
    # the coast cut short at t = 300 s (before the apogee at 569.7 s) reaches less height; 2000 s: the apogee
    r = service.client.post("/v1/studies", json={
        "kind": "ocp", "preset": "two-stage-ascent", "mode": "independent",
        "sweeps": [{"path": "phases.coast.time.final_upper", "values": [300.0, 2000.0]}]})
    assert r.status_code == 202, r.text
    study_id = r.json()["id"]
    deadline = time.monotonic() + 300
    while (body := service.client.get(f"/v1/studies/{study_id}").json())["status"] == "running":
        assert time.monotonic() < deadline, body
        time.sleep(0.5)
    assert body["status"] == "finished", body
    rows = service.client.get(f"/v1/studies/{study_id}/result").json()["rows"]
    assert [row["status"] for row in rows] == ["succeeded"] * 2, rows
    short, full = (service.result(row["job_id"]) for row in rows)
    assert short["phases"][2]["tf"] == pytest.approx(300.0, abs=1e-4)   # IPOPT relaxes bounds by 1e-8 (relative)
    assert short["objective"]["value"] < full["objective"]["value"]
    assert full["objective"]["value"] == pytest.approx(CASES["two-stage-ascent"]["optimum"], abs=0.5)
