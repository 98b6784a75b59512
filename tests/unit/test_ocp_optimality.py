"""Costates and the Hamiltonian of an ``ocp`` answer (multiple shooting, from the defect multipliers) against
the brachistochrone's analytic ones, and ``verification.optimality`` (``shared/specs/ocp.md``, "Optimality").

The brachistochrone (minimum time, x' = v sin(theta), y' = -v cos(theta), v' = g cos(theta), v(tf) free):
H = lx v sin(theta) - ly v cos(theta) + lv g cos(theta) does not name t, x or y, so lx and ly are constant
and H is constant; the free final time with Phi = tf gives H = -1; v free at tf gives lv(tf) = 0; at t0,
v = 0 and H = -1 give lv(t0) = -1 / (g cos(theta(t0))); with stationarity at tf, lx = -sin(theta) / v
along the whole path (Snell's law: sin(theta) / v is constant).  The tolerances are the transcription's:
50 RK4 intervals with linear controls carry the control's discretization error (about 0.4% in theta / v
near t0, where v is small), the multipliers themselves converge to IPOPT's tolerance.
"""
from __future__ import annotations

import numpy as np
import pytest

from solvers.ocp import PRESETS, parse_problem, solve

G = 9.80665


@pytest.fixture(scope="module")
def brachistochrone():
    sol = solve(parse_problem(PRESETS["brachistochrone"]["params"]))
    assert sol.status.ok
    return sol


def test_the_costates_are_the_analytic_ones(brachistochrone):
    ph = brachistochrone.phases[0]
    lam, tr = ph["costates"], ph["trajectory"]
    theta, v = np.asarray(tr["theta"]), np.asarray(tr["v"])
    assert np.ptp(lam["x"]) <= 1e-8 * abs(lam["x"][0]) and np.ptp(lam["y"]) <= 1e-8 * abs(lam["y"][0])
    assert lam["x"] == pytest.approx(-np.sin(theta[-1]) / v[-1], rel=1e-6)       # where lv = 0 exactly
    assert lam["x"][1:] == pytest.approx(-np.sin(theta[1:]) / v[1:], rel=1e-2)    # Snell along the path
    assert lam["v"][-1] == pytest.approx(0.0, abs=1e-8)
    assert lam["v"][0] == pytest.approx(-1.0 / (G * np.cos(theta[0])), rel=1e-4)


def test_the_hamiltonian_is_minus_one_and_optimality_holds(brachistochrone):
    H = brachistochrone.phases[0]["hamiltonian"]
    assert H == pytest.approx(-1.0, abs=1e-4)
    opt = brachistochrone.verification["optimality"]
    assert opt["held"] and set(opt["checks"]) == {"hamiltonian_constant", "hamiltonian_final", "stationarity"}
    assert opt["checks"]["hamiltonian_final"]["expected"] == -1.0


def test_stationarity_is_checked_off_an_active_path_constraint_only():
    """A path constraint that binds (theta <= 1.2 on the last part of the descent): its multiplier is not
    in H, so its arc is left out of the stationarity check, which holds on the free arc."""
    params = {**PRESETS["brachistochrone"]["params"],
              "path": [{"name": "theta_cap", "expr": "theta", "upper": 1.2}]}
    sol = solve(parse_problem(params))
    assert sol.status.ok
    theta = np.asarray(sol.trajectory["theta"])
    on_arc = int(np.sum(theta > 1.2 - 1e-3 * 1.2))
    assert on_arc > 5                                          # the constraint binds
    stationarity = sol.verification["optimality"]["checks"]["stationarity"]
    assert stationarity["held"] and stationarity["nodes"] <= theta.size - on_arc


def test_the_result_carries_costates_and_the_headline_says_verified():
    from app.kinds.ocp import SPEC
    from app.kinds.ocp.headlines import headlines
    from tests.support import RecordingContext

    params = PRESETS["brachistochrone"]["params"]
    out = SPEC.run(SPEC.params_model.model_validate(params), RecordingContext())
    assert set(out.result["costates"]) == {"x", "y", "v"}
    assert len(out.result["hamiltonian"]) == len(out.result["trajectory"]["t"])
    words = [h.text for h in headlines(out.result, params)]
    assert any(w.startswith("optimality verified") for w in words), words
