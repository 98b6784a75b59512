"""POST /v1/lambert on a bare FastAPI app with the router mounted."""
import math

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from app.routes.lambert import router
from app.settings import get_settings
from solvers.astro.kepler import propagate

MU = 398600.4418e9


@pytest.fixture(scope="module")
def client():
    app = FastAPI()
    app.include_router(router)
    # the route reads the key check's settings from the app, as create_app() sets them (auth off in tests)
    app.state.settings = get_settings()
    return TestClient(app)


CURTIS = {"r1_m": [5000e3, 10000e3, 2100e3], "r2_m": [-14600e3, 2500e3, 7000e3], "tof_s": 3600.0}


def test_curtis_example_in_si(client):
    resp = client.post("/v1/lambert", json={"mu_m3_s2": 398600e9, "problems": [CURTIS]})
    assert resp.status_code == 200
    (sol,) = resp.json()["solutions"]
    assert sol["converged"] is True
    np.testing.assert_allclose(sol["v1_mps"], [-5992.5, 1925.4, 3245.6], atol=0.1)
    np.testing.assert_allclose(sol["v2_mps"], [-3312.5, -4196.6, -385.29], atol=0.1)


def test_mixed_branches_keep_request_order(client):
    rng = np.random.default_rng(7)
    problems = []
    for k in range(30):
        r1 = (rng.normal(size=3) * 8000e3).tolist()
        r2 = (rng.normal(size=3) * 9000e3).tolist()
        revs = k % 3
        problems.append({"r1_m": r1, "r2_m": r2, "tof_s": 4000.0 + 9000.0 * revs + 100.0 * k,
                         "revolutions": revs, "prograde": bool(k % 2)})
    resp = client.post("/v1/lambert", json={"problems": problems})
    assert resp.status_code == 200
    sols = resp.json()["solutions"]
    assert len(sols) == 30
    assert sum(s["converged"] for s in sols) >= 15
    for p, s in zip(problems, sols):
        assert s["revolutions"] == p["revolutions"] and s["prograde"] == p["prograde"]
        if p["revolutions"] == 0:
            assert s["converged"]
        if not s["converged"]:
            assert s["v1_mps"] is None
            continue
        r, _ = propagate(MU, p["r1_m"], s["v1_mps"], p["tof_s"])
        assert np.linalg.norm(r - np.array(p["r2_m"])) / np.linalg.norm(p["r2_m"]) < 1e-6


@pytest.mark.parametrize("problem,field", [
    ({**CURTIS, "r1_m": [1.0, 2.0]}, "r1_m"),
    ({**CURTIS, "r2_m": [1.0, 2.0, 3.0, 4.0]}, "r2_m"),
    ({**CURTIS, "tof_s": 0.0}, "tof_s"),
    ({**CURTIS, "tof_s": -5.0}, "tof_s"),
    ({**CURTIS, "r1_m": [0.0, 0.0, 0.0]}, "r1_m"),
    ({**CURTIS, "revolutions": -1}, "revolutions"),
    ({**CURTIS, "extra": 1}, "extra"),
])
def test_bad_problems_are_422(client, problem, field):
    resp = client.post("/v1/lambert", json={"problems": [problem]})
    assert resp.status_code == 422
    assert field in str(resp.json()["detail"])


def test_nan_is_422(client):
    body = '{"problems": [{"r1_m": [NaN, 1, 2], "r2_m": [1, 2, 3], "tof_s": 100}]}'
    resp = client.post("/v1/lambert", content=body, headers={"content-type": "application/json"})
    assert resp.status_code == 422
    assert "r1_m" in str(resp.json()["detail"])


def test_cap_is_enforced(client, monkeypatch):
    settings = get_settings()
    monkeypatch.setattr(settings, "lambert_max_problems", 3)
    resp = client.post("/v1/lambert", json={"problems": [CURTIS] * 4})
    assert resp.status_code == 422
    assert "problems" in str(resp.json()["detail"]) and "3" in str(resp.json()["detail"])
    assert client.post("/v1/lambert", json={"problems": [CURTIS] * 3}).status_code == 200


def test_empty_list_is_422(client):
    assert client.post("/v1/lambert", json={"problems": []}).status_code == 422


@pytest.mark.parametrize("problem, mu", [
    ({"r1_m": [1e300, 0, 0], "r2_m": [0, 7e6, 0], "tof_s": 3600.0}, None),
    ({"r1_m": [7e6, 0, 0], "r2_m": [0, 7e6, 0], "tof_s": 1e300}, None),
    ({"r1_m": [7e6, 0, 0], "r2_m": [0, 7e6, 0], "tof_s": 3600.0}, 1e300),
])
def test_absurd_magnitudes_are_422(client, problem, mu):
    body = {"problems": [problem], **({"mu_m3_s2": mu} if mu else {})}
    r = client.post("/v1/lambert", json=body)
    assert r.status_code == 422, r.text
