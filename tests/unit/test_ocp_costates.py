"""Costates of both transcriptions against closed forms (``shared/specs/ocp.md``, "Optimality"): multiple
shooting's from its defects' multipliers, LGL's by the integral form's costate mapping (multipliers over the
quadrature weights, with the endpoint corrections; :mod:`solvers.ocp.costates`).

Each tolerance is the grid's: RK4's discrete adjoint and LGL's degree-4 segments are fourth order in the
interval width ``h`` (checked: halving ``h`` divides the error by more than 8), so the error relative to the
costate's size is held to ``(h / T)^4``; Bryson-Denham's order-2 state constraint puts atoms of its
multiplier at the junctions, which a transcription spreads over a node's neighbourhood: first order in the
largest node spacing there.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from solvers.ocp import PRESETS, parse_problem, solve

G = 9.80665


def _solve(name: str, transcription: dict):
    sol = solve(parse_problem({**PRESETS[name]["params"], "transcription": transcription}))
    assert sol.status.ok, sol.status.message
    return sol, sol.phases[0]


# --- the scalar LQ regulator: lambda(t) = p(t) x(t), p the Riccati solution in closed form ---------
_P1, _P2 = 1 + math.sqrt(2), 1 - math.sqrt(2)
_K = (_P1 / _P2) * math.exp(-(_P1 - _P2) * 1.0)


def _riccati(t: np.ndarray) -> np.ndarray:
    """p(t) with p' = p^2 - 2p - 1, p(1) = 0: (p - p1)/(p - p2) = K exp((p1 - p2) t)."""
    E = _K * np.exp((_P1 - _P2) * t)
    return (_P1 - E * _P2) / (1 - E)


def _lq_error(transcription: dict) -> float:
    sol, ph = _solve("scalar-lq-riccati", transcription)
    t, x, lam = (np.asarray(a) for a in (ph["trajectory"]["t"], ph["trajectory"]["x"], ph["costates"]["x"]))
    assert ph["verification"]["optimality"]["held"], ph["verification"]["optimality"]["message"]
    return float(np.max(np.abs(lam - _riccati(t) * x)) / np.max(np.abs(lam)))


@pytest.mark.parametrize("coarse, fine, h", [
    ({"method": "multiple_shooting", "intervals": 20, "control": "linear", "substeps": 2},
     {"method": "multiple_shooting", "intervals": 40, "control": "linear", "substeps": 2}, 1 / 20),
    ({"method": "lgl", "intervals": 4, "nodes": 5}, {"method": "lgl", "intervals": 8, "nodes": 5}, 1 / 4),
])
def test_lq_costates_are_the_riccati_ones_to_fourth_order(coarse, fine, h):
    e1, e2 = _lq_error(coarse), _lq_error(fine)
    assert e1 <= h ** 4 and e2 <= (h / 2) ** 4, (e1, e2)
    assert e2 <= e1 / 8, (e1, e2)                     # fourth order seen (16 in theory), more than third


# --- the brachistochrone under LGL (multiple shooting's: tests/unit/test_ocp_optimality.py) ---------
def test_lgl_brachistochrone_costates_are_the_analytic_ones():
    """lx, ly constant; lx = -sin(theta)/v (Snell) along the path; lv(tf) = 0 (v free); lv(t0) =
    -1/(g cos theta(t0)) (H = -1 at v = 0); H = -1 throughout (Phi = tf).  10 segments of 5 nodes: h/T = 0.1,
    tolerance (h/T)^4 = 1e-4 of each quantity's size."""
    sol, ph = _solve("brachistochrone", {"method": "lgl", "intervals": 10, "nodes": 5})
    lam, tr = ph["costates"], ph["trajectory"]
    theta, v = np.asarray(tr["theta"]), np.asarray(tr["v"])
    tol = 0.1 ** 4
    assert np.ptp(lam["x"]) <= tol * abs(lam["x"][0]) and np.ptp(lam["y"]) <= tol * abs(lam["y"][0])
    assert lam["x"][1:] == pytest.approx(-np.sin(theta[1:]) / v[1:], rel=tol)
    assert abs(lam["v"][-1]) <= tol * np.max(np.abs(lam["v"]))
    assert lam["v"][0] == pytest.approx(-1.0 / (G * np.cos(theta[0])), rel=tol)
    assert ph["hamiltonian"] == pytest.approx(-1.0, abs=tol)
    opt = ph["verification"]["optimality"]
    assert opt["held"] and set(opt["checks"]) == {"hamiltonian_constant", "hamiltonian_final", "stationarity",
                                                  "minimum_principle", "transversality"}
    # the mapping's own end value against the boundary multipliers' (lv(tf) = 0): the endpoint correction
    assert opt["checks"]["transversality"]["value"] <= tol


# --- Bryson-Denham: x <= l = 1/9 touched on [1/3, 2/3] ----------------------------------------------
@pytest.mark.parametrize("transcription", [
    {"method": "multiple_shooting", "intervals": 90, "control": "linear", "substeps": 2},
    {"method": "lgl", "intervals": 3, "nodes": 8},          # the junctions on segment ends
])
def test_bryson_denham_costates_off_and_on_the_state_constraint(transcription):
    """Off the arc u = -lv (stationarity of u^2/2 + lx v + lv u) with u = -6 (1 - 3t) before it and its
    mirror after, so lv = 6 - 18 t, lx = 18 before, lv = 18 t - 12, lx = -18 after; on the arc (u = 0) both
    vanish with the constraint's multiplier adjoined directly (lx jumps at the junctions)."""
    sol, ph = _solve("bryson-denham", transcription)
    t = np.asarray(ph["trajectory"]["t"])
    lam = {k: np.asarray(v) for k, v in ph["costates"].items()}
    lx = np.where(t < 1 / 3, 18.0, np.where(t > 2 / 3, -18.0, 0.0))
    lv = np.where(t < 1 / 3, 6 - 18 * t, np.where(t > 2 / 3, 18 * t - 12, 0.0))
    away = (np.abs(t - 1 / 3) > 1e-9) & (np.abs(t - 2 / 3) > 1e-9)     # lx is two-valued at a junction
    spacing = float(np.max(np.diff(t)))
    assert np.max(np.abs(lam["x"] - lx)[away]) <= 18.0 * spacing
    assert np.max(np.abs(lam["v"] - lv)) <= 6.0 * spacing
    assert ph["verification"]["optimality"]["held"], ph["verification"]["optimality"]["message"]
