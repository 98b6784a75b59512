"""The intercept kind through the whole service: HTTP submit, real worker, stored result."""
import pytest

pytestmark = pytest.mark.integration


def test_long_range_intercept_impulsive(service):
    resp = service.submit("intercept", preset="long-range-intercept", params={"methods": ["impulsive"]})
    assert resp.status_code == 202, resp.text
    job = resp.json()
    assert job["params"]["methods"] == ["impulsive"]
    assert job["params"]["g0_mps2"] == 9.80665
    done = service.wait(job["id"], timeout=180)
    assert done["status"] == "succeeded", done
    assert done["progress"] == 1.0
    result = service.result(job["id"])
    best = result["impulsive"]["best"]
    assert abs(best["delta_v_mps"] - 2302.48) < 0.01
    assert abs(best["t_man_s"] - 3142.5) < 0.5
    assert abs(best["fuel_kg"] - 271.4) < 0.05
    scan = result["impulsive"]["scan"]  # thinned by default (test_results_http checks every minimum survives)
    assert len(scan["t_man_s"]) == len(scan["delta_v_mps"]) > 250 and scan["points_stored"] > 10000
    assert result["finite_thrust"] is None


def test_lambert_endpoint_on_the_service(service):
    body = {"mu_m3_s2": 398600e9, "problems": [
        {"r1_m": [5000e3, 10000e3, 2100e3], "r2_m": [-14600e3, 2500e3, 7000e3], "tof_s": 3600.0}]}
    resp = service.client.post("/v1/lambert", json=body)
    assert resp.status_code == 200, resp.text
    v1 = resp.json()["solutions"][0]["v1_mps"]
    assert abs(v1[0] + 5992.5) < 0.1 and abs(v1[1] - 1925.4) < 0.1 and abs(v1[2] - 3245.6) < 0.1


def test_bad_intercept_params_are_422(service):
    resp = service.submit("intercept", params={"interceptor": {"propellant_kg": 900.0}})
    assert resp.status_code == 422
    assert "propellant_kg" in resp.text
