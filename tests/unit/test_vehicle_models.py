"""Vehicles, planets and atmospheres as data (issue 15 item 1): aero tables, Sutton-Graves,
log-density tables, the Mars entry case, and /v1/vehicles."""
from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np
import pytest

from app.kinds.reentry.params import ReentryParams
from solvers import reentry as rs
from solvers.common import Outcome
from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.models import vehicles
from solvers.models.aerodynamics import AeroTable, sample_polynomials
from solvers.models.atmosphere import Atmosphere
from solvers.models.heating import SuttonGraves
from solvers.models.vehicle_data import (
    aero_numbers,
    heating_numbers,
    model_key,
    vehicle_from_dict,
    vehicle_to_dict,
    with_symbols,
)
from solvers.reentry.guess import simulate_constant_controls
from tests.unit import test_api_contract

DEG = math.pi / 180


def _shuttle_table(mach=(1.0,)):
    return sample_polynomials(cl_coeffs=sh.SHUTTLE.cl_coeffs, cd_coeffs=sh.SHUTTLE.cd_coeffs,
                              alpha_deg=np.arange(-90.0, 90.1, 5.0), mach=mach)


def test_table_matches_the_polynomial_it_was_sampled_from_and_keeps_the_scales():
    # A cubic B-spline through samples of a quadratic reproduces it (also off the breakpoints,
    # and along Mach where the table is constant).
    veh = dataclasses.replace(sh.SHUTTLE, aero_table=_shuttle_table(mach=(0.5, 5.0, 15.0, 40.0)),
                              cd_scale=1.1, cl_scale=0.9)
    poly = dataclasses.replace(sh.SHUTTLE, cd_scale=1.1, cl_scale=0.9)
    x = np.tile(np.array(sh.BETTS_INITIAL_STATE)[:, None], (1, 5))
    x[3] = [7800.0, 5000.0, 3000.0, 1000.0, 300.0]
    u = np.vstack([np.radians([-33.3, 0.0, 12.7, 17.0, 41.1]), np.full(5, -1.0)])
    _, cl_t, cd_t = dyn.aero(x, u, veh, cd_scale=1.05)
    _, cl_p, cd_p = dyn.aero(x, u, poly, cd_scale=1.05)
    assert np.allclose(cl_t, cl_p, rtol=0, atol=1e-12) and np.allclose(cd_t, cd_p, rtol=0, atol=1e-12)
    # numpy and CasADi evaluate the same spline
    xs, us = ca.SX.sym("x", 6), ca.SX.sym("u", 2)
    f = ca.Function("f", [xs, us], [dyn.eom(xs, us, veh, ca)])
    assert np.allclose(np.asarray(f(x[:, 2], u[:, 2])).ravel(), dyn.eom(x[:, 2], u[:, 2], veh), rtol=1e-13)


@pytest.mark.slow
def test_table_vehicle_reproduces_betts_max_crossrange():
    veh = dataclasses.replace(sh.SHUTTLE, aero_table=_shuttle_table())
    s = rs.solve(rs.ReentryProblem(vehicle=veh, intervals=100))
    assert s.status.outcome is Outcome.OPTIMAL
    assert s.objective_value / DEG == pytest.approx(34.1412, abs=0.01)        # polynomial: 34.14118
    assert s.tf_s == pytest.approx(2008.59, abs=0.5)


def test_sutton_graves_matches_a_hand_calculation():
    # Earth, r_n = 0.5 m, at 60 km in an exponential atmosphere (1.225 kg/m^3, 7200 m), 7000 m/s:
    # rho = 1.225 exp(-60000 / 7200) = 1.225 * 2.40369e-4 = 2.94453e-4 kg/m^3,
    # sqrt(rho / r_n) = sqrt(5.88905e-4) = 0.0242674, v^3 = 3.43e11,
    # q = 1.7415e-4 * 0.0242674 * 3.43e11 = 1.44957e6 W/m^2.
    veh = dataclasses.replace(sh.SHUTTLE, heating=SuttonGraves(nose_radius_m=0.5),
                              atmosphere=Atmosphere(kind="exponential", rho0_kg_m3=1.225, scale_height_m=7200.0))
    x = np.array([60000.0, 0.0, 0.0, 7000.0, -0.01, 1.0])
    q = dyn.heat_rate(x, np.array([0.3, 0.0]), veh)
    assert q == pytest.approx(1.44957e6, rel=1e-5)
    # the vehicle's own constant wins over the planet's; Mars' constant with the Mars planet
    own = dataclasses.replace(veh, heating=SuttonGraves(nose_radius_m=0.5, k=2e-4))
    assert dyn.heat_rate(x, np.zeros(2), own) == pytest.approx(q * 2e-4 / 1.7415e-4, rel=1e-12)
    mars = dataclasses.replace(veh, planet=vehicles.MARS)
    assert dyn.heat_rate(x, np.zeros(2), mars) == pytest.approx(q * 1.9027e-4 / 1.7415e-4, rel=1e-12)


def test_log_density_table_reproduces_the_exponential_it_was_sampled_from():
    exp = sh.BETTS_ATMOSPHERE
    h = np.arange(0.0, 100001.0, 5000.0)
    table = Atmosphere(kind="table", altitudes_m=h, densities_kg_m3=exp.density(h))
    hh = np.linspace(-2000.0, 110000.0, 2001)        # off the breakpoints, and beyond both ends
    assert np.max(np.abs(table.density(hh) / exp.density(hh) - 1.0)) < 1e-9
    # state tolerance: the same glide through either atmosphere ends at the same state
    p_exp = rs.ReentryProblem()
    p_tab = rs.ReentryProblem(vehicle=dataclasses.replace(sh.SHUTTLE, atmosphere=table))
    g_exp = simulate_constant_controls(p_exp, alpha_rad=17 * DEG, bank_rad=-60 * DEG)
    g_tab = simulate_constant_controls(p_tab, alpha_rad=17 * DEG, bank_rad=-60 * DEG)
    assert g_tab.t[-1] == g_exp.t[-1]
    dx = np.abs(g_tab.x[:, -1] - g_exp.x[:, -1])
    assert dx[0] < 1e-3 and dx[3] < 1e-5 and np.all(dx[[1, 2, 4, 5]] < 1e-9)


def test_log_density_table_is_differentiable():
    h = np.arange(0.0, 130001.0, 5000.0)
    rho, _ = vehicles.mars_glenn_profile(h)
    table = Atmosphere(kind="table", altitudes_m=h, densities_kg_m3=rho)
    hs = ca.SX.sym("h")
    f = ca.Function("f", [hs], [table.density(hs)])
    df = ca.Function("df", [hs], [ca.jacobian(table.density(hs), hs)])
    for h0 in (1234.0, 37000.0, 88888.0, 129000.0, 135000.0, -500.0):
        fd = (float(f(h0 + 0.5)) - float(f(h0 - 0.5))) / 1.0
        assert float(df(h0)) == pytest.approx(fd, rel=1e-6), h0
        assert float(f(h0)) == pytest.approx(table.density(h0), rel=1e-12)


def test_vehicle_numbers_as_nlp_parameters_give_the_same_physics():
    # the NLP sees mass, area, aero polynomials, scales and the Sutton-Graves numbers as
    # parameters: a vehicle rebuilt from symbols must evaluate like the numeric one
    for v in (dataclasses.replace(sh.SHUTTLE, heating=SuttonGraves(nose_radius_m=0.7)), vehicles.MSL):
        aero, heat = aero_numbers(v), heating_numbers(v)
        pa, ph = ca.SX.sym("a", len(aero)), ca.SX.sym("q", len(heat))
        sym = dataclasses.replace(v, **with_symbols(v, pa, ph))
        xs, us = ca.SX.sym("x", 6), ca.SX.sym("u", 2)
        f = ca.Function("f", [xs, us, pa, ph], [ca.vertcat(dyn.eom(xs, us, sym, ca), dyn.heat_rate(xs, us, sym, ca))])
        x = np.array([60000.0, 0.1, 0.2, 5000.0, -0.1, 1.0])
        u = np.array([-16.0 * DEG, 0.5])
        want = np.concatenate([dyn.eom(x, u, v), [dyn.heat_rate(x, u, v)]])
        assert np.allclose(np.asarray(f(x, u, aero, heat)).ravel(), want, rtol=1e-12)
    # the cache key holds the structure, not the parameters
    heavier = dataclasses.replace(vehicles.MSL, mass_kg=4000.0, heating=SuttonGraves(nose_radius_m=2.0))
    assert model_key(heavier) == model_key(vehicles.MSL) != model_key(sh.SHUTTLE)


def test_vehicle_round_trips_through_json():
    for preset in vehicles.VEHICLES.values():
        v = dataclasses.replace(preset.vehicle, cd_scale=1.2)
        assert vehicle_from_dict(vehicle_to_dict(v)) == v


@pytest.mark.slow
def test_mars_entry_solves_and_its_repropagation_meets_the_terminal_conditions():
    import json

    from app.kinds.reentry import SPEC, run
    from app.kinds.reentry.edge import to_problem
    from tests.support import RecordingContext
    params = SPEC.params_model.model_validate(next(p for p in SPEC.presets
                                                   if p.name == "mars-msl-max-crossrange").params)
    assert to_problem(params).vehicle == vehicles.MSL
    out = run(params, RecordingContext())
    assert out.status == "succeeded"
    res = json.loads(json.dumps(out.result, allow_nan=False))
    SPEC.result_model.model_validate(res)
    assert res["solver"]["status"] == "Solve_Succeeded"
    assert res["objective"]["value"] == pytest.approx(1.1005, abs=2e-3)          # deg of crossrange
    final, ver = res["final"], res["verification"]
    assert final["altitude_m"] == pytest.approx(10000.0, abs=1e-6)
    assert final["speed_mps"] == pytest.approx(450.0, abs=1e-6)
    # the re-propagated flight ends where the terminal conditions ask: 10 m, 1 m/s, 0.01 deg
    assert ver["ok"] and abs(ver["final_altitude_diff_m"]) < 10.0 and abs(ver["final_speed_diff_mps"]) < 1.0
    for angle in ("latitude", "longitude", "flight_path", "heading"):
        assert abs(ver[f"final_{angle}_diff_deg"]) < 0.01, angle


def test_aero_table_rejects_malformed_tables():
    with pytest.raises(ValueError, match="strictly increasing"):
        AeroTable(alpha_deg=(0, 1, 3, 2), mach=(1,), cl=[[1]] * 4, cd=[[1]] * 4)
    with pytest.raises(ValueError, match="shape"):
        AeroTable(alpha_deg=(0, 1, 2, 3), mach=(1, 2, 3, 4), cl=[[1]] * 4, cd=[[1]] * 4)
    with pytest.raises(ValueError, match="positive"):
        Atmosphere(kind="table", altitudes_m=(0, 1, 2, 3), densities_kg_m3=(1, 0, 1, 1))


# --- the API edge --------------------------------------------------------------------------------
client = test_api_contract.client     # the API fixture: the app on SQLite, no broker contacted
def test_vehicles_route_lists_the_presets(client):
    listed = {v["name"]: v for v in client.get("/v1/vehicles").json()}
    assert {"shuttle", "msl"} <= set(listed)
    msl = client.get("/v1/vehicles/msl").json()
    assert msl == listed["msl"]
    assert msl["vehicle"]["mass_kg"] == 3257.0 and msl["vehicle"]["area_m2"] == pytest.approx(15.904, abs=1e-3)
    assert msl["vehicle"]["heating"] == {"model": "sutton_graves", "nose_radius_m": 1.125, "k": None}
    assert msl["planet"]["preset"] == "mars" and msl["atmosphere"]["kind"] == "table"
    assert listed["shuttle"]["vehicle"]["cl_coeffs"] == [-0.20704, 0.029244]
    r = client.get("/v1/vehicles/nope")
    assert r.status_code == 404 and "msl" in r.json()["detail"]


def test_unknown_vehicle_is_a_422_on_submit(client):
    r = client.post("/v1/jobs", json={"kind": "reentry", "params": {"vehicle": {"preset": "apollo"}}})
    assert r.status_code == 422
    assert "vehicle" in str(r.json())


@pytest.mark.parametrize("table, rule", [
    ({"alpha_deg": [0, 10, 5, 20], "mach": [1], "cl": [[0.1]] * 4, "cd": [[1.0]] * 4}, "strictly increasing"),
    ({"alpha_deg": [0, 5, 10, 20], "mach": [1], "cl": [[0.1]] * 3, "cd": [[1.0]] * 4}, "shape"),
    ({"alpha_deg": [0, 5, 10, 20], "mach": [1, 2], "cl": [[0.1, 0.1]] * 4, "cd": [[1.0, 1.0]] * 4}, "at least 4"),
])
def test_malformed_aero_table_is_a_422(client, table, rule):
    r = client.post("/v1/jobs", json={"kind": "reentry", "params": {"vehicle": {"aero_table": table}}})
    assert r.status_code == 422
    assert rule in str(r.json())


def test_inline_vehicle_planet_and_atmosphere_reach_the_solver():
    from app.kinds.reentry.edge import to_problem
    params = ReentryParams.model_validate({
        "vehicle": {"preset": "shuttle", "heating": {"model": "sutton_graves", "nose_radius_m": 0.8}},
        "planet": {"preset": "earth", "sutton_graves_k": 1.8e-4},
        "atmosphere": {"kind": "exponential", "rho0_kg_m3": 1.2, "scale_height_m": 7000.0}})
    v = to_problem(params).vehicle
    assert v.heating == SuttonGraves(nose_radius_m=0.8) and v.planet.sutton_graves_k == 1.8e-4
    assert v.atmosphere.density(7000.0) == pytest.approx(1.2 / math.e, rel=1e-12)
    assert to_problem(ReentryParams()).vehicle == sh.SHUTTLE        # defaults: today's shuttle


@pytest.mark.parametrize("name", sorted(vehicles.VEHICLES))
def test_a_listed_vehicle_pastes_into_params_unchanged(client, name):
    """Issue 28: what GET /v1/vehicles/{name} returns is what params.vehicle (and planet, atmosphere) take,
    and it flies the same vehicle as naming the preset (every number, table, model, planet, atmosphere)."""
    import dataclasses

    from app.kinds.reentry.edge import vehicle_of
    from app.kinds.reentry.params import ReentryParams, ReentryVehicle
    from app.kinds.reentry.vehicle import VehicleData
    from solvers.models.vehicle_data import vehicle_to_dict

    assert set(VehicleData.model_fields) == set(ReentryVehicle.model_fields)
    out = client.get(f"/v1/vehicles/{name}").json()
    pasted = ReentryParams.model_validate({k: out[k] for k in ("vehicle", "planet", "atmosphere")})
    named = ReentryParams.model_validate({"vehicle": {"preset": name}})
    assert vehicle_to_dict(vehicle_of(pasted)) == vehicle_to_dict(vehicle_of(named))
    base = dataclasses.replace(vehicles.vehicle_preset(name).vehicle, rotating_earth=False)
    assert vehicle_to_dict(vehicle_of(named)) == vehicle_to_dict(base)
