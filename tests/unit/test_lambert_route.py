"""POST /v1/lambert on a bare FastAPI app with the router mounted."""
import math

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from app.api.routes.lambert import router
from app.runtime.settings import get_settings
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


def test_periapsis_and_through_planet_flag(client):
    # A near-radial plunge from 20000 km to 30000 km on the other side in a short time dives
    # through the Earth; a Hohmann-like half ellipse from 7000 km to 42000 km does not.
    ang = math.radians(179.0)
    plunge = {"r1_m": [20000e3, 0.0, 0.0], "r2_m": [30000e3 * math.cos(ang), 30000e3 * math.sin(ang), 0.0],
              "tof_s": 3000.0}
    a = 0.5 * (7000e3 + 42000e3)
    hohmann = {"r1_m": [7000e3, 0.0, 0.0], "r2_m": [42000e3 * math.cos(ang), 42000e3 * math.sin(ang), 0.0],
               "tof_s": math.pi * math.sqrt(a ** 3 / MU) * 0.995}
    body = {"mu_m3_s2": MU, "problems": [plunge, hohmann]}
    resp = client.post("/v1/lambert", json=body)
    assert resp.status_code == 200
    s_plunge, s_hohmann = resp.json()["solutions"]
    assert s_plunge["converged"] and s_hohmann["converged"]
    assert s_plunge["periapsis_m"] < 6378137.0 and s_plunge["through_planet"] is True
    assert s_hohmann["periapsis_m"] == pytest.approx(7000e3, rel=1e-3) and s_hohmann["through_planet"] is False
    # the periapsis is the smallest radius along the propagated arc
    ts = np.linspace(0.0, plunge["tof_s"], 20001)
    r, _ = propagate(MU, np.array(plunge["r1_m"]), np.array(s_plunge["v1_mps"]), ts)
    assert s_plunge["periapsis_m"] == pytest.approx(np.linalg.norm(r, axis=1).min(), rel=1e-4)
    # another body's radius, and no check at all
    small = client.post("/v1/lambert", json={**body, "body_radius_m": 1000.0}).json()["solutions"]
    assert [s["through_planet"] for s in small] == [s_plunge["periapsis_m"] < 1000.0, False]
    none = client.post("/v1/lambert", json={**body, "body_radius_m": None}).json()["solutions"]
    assert [s["through_planet"] for s in none] == [None, None]
    assert none[0]["periapsis_m"] == s_plunge["periapsis_m"]
    assert client.post("/v1/lambert", json={**body, "body_radius_m": -1.0}).status_code == 422


def test_random_cases_through_the_planet_are_flagged(client):
    # Random LEO..GEO geometry: a good share of the arcs dip below the Earth's surface (issue 15
    # saw 60 of 178 unflagged); every such answer is now flagged, and only those.
    rng = np.random.default_rng(3)
    problems = []
    for _ in range(200):
        r1 = rng.normal(size=3)
        r2 = rng.normal(size=3)
        r1 *= rng.uniform(6700e3, 42000e3) / np.linalg.norm(r1)
        r2 *= rng.uniform(6700e3, 42000e3) / np.linalg.norm(r2)
        problems.append({"r1_m": r1.tolist(), "r2_m": r2.tolist(), "tof_s": float(rng.uniform(600.0, 40000.0))})
    sols = client.post("/v1/lambert", json={"mu_m3_s2": MU, "problems": problems}).json()["solutions"]
    flagged = [s["through_planet"] for s in sols if s["converged"]]
    assert all(s["converged"] for s in sols)
    assert 20 <= sum(flagged) <= 150
    assert all(s["through_planet"] == (s["periapsis_m"] < 6378137.0) for s in sols)
    ends = [min(np.linalg.norm(p["r1_m"]), np.linalg.norm(p["r2_m"])) for p in problems]
    assert all(s["periapsis_m"] <= e * (1 + 1e-12) for s, e in zip(sols, ends))
