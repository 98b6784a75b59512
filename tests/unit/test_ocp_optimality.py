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

from typing import Any

import numpy as np
import pytest

from solvers.common import Outcome
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
    assert opt["held"] and set(opt["checks"]) == {"hamiltonian_constant", "hamiltonian_final", "stationarity",
                                                  "minimum_principle", "transversality"}
    assert opt["checks"]["transversality"]["end"] == "final" and opt["checks"]["transversality"]["state"] == "v"
    # -dPhi/dtf with Phi = tf, read off the events' gradient and tf's multipliers: -1 to IPOPT's tolerance
    assert opt["checks"]["hamiltonian_final"]["expected"] == pytest.approx(-1.0, abs=1e-8)


def test_the_minimum_principle_holds_between_the_nodes(brachistochrone):
    """theta minimises H over its bounds at every sample of the re-flight, not only at the nodes."""
    mp = brachistochrone.verification["optimality"]["checks"]["minimum_principle"]
    nodes = len(brachistochrone.trajectory["t"])
    assert mp["held"] and mp["samples"] > 2 * nodes
    assert "minimum_principle" in brachistochrone.verification["optimality"]["message"]


def test_a_bang_bang_answer_holds_every_check_with_the_allowance_its_mesh_gives():
    """The time-optimal double integrator: u = -1 then +1, each the minimiser of H = lx v + lv u over
    [-1, 1] (its switching function lv changes sign at the switch, t = 1, a node of 20 constant intervals).
    The multipliers fix lv's sign per interval, not where it crosses zero: anywhere between the midpoints of
    the two intervals around the switch (h = 0.1), where |d lv/dt| = lx = 1, so H may jump at that node by
    up to |du| |lx| h / 2 = 2 * 1 * 0.05 = 0.1 (of H's terms, about 1): the allowance.  H itself is constant
    on each arc (dH/dt = lx u + lv' u = 0), so the spread is that one jump."""
    sol = solve(parse_problem(PRESETS["double-integrator-min-time"]["params"]))
    assert sol.status.ok
    u = np.asarray(sol.trajectory["u"])
    assert np.all(np.abs(np.abs(u) - 1.0) <= 1e-6)                       # bang-bang: the bounds only
    opt = sol.verification["optimality"]
    assert opt["held"] and sol.status.outcome is Outcome.OPTIMAL, opt
    hc = opt["checks"]["hamiltonian_constant"]
    assert 0.09 <= hc["allowance"] <= 0.11 and hc["tolerance"] == pytest.approx(0.01 + hc["allowance"])
    assert 0.01 < hc["value"] <= hc["allowance"]          # the jump at the switch is real, and within it
    assert opt["checks"]["minimum_principle"]["held"]
    # one value per arc: H varies by less than 1e-6 of its terms away from the switch node
    H = np.asarray(sol.phases[0]["hamiltonian"])
    assert np.ptp(H[:10]) <= 1e-6 and np.ptp(H[11:]) <= 1e-6


# Two local optima: x' = u, x(0) = 0, u in [-2, 2], minimise int (u^2 - 1)^2 + 0.3 x over 1 s.  The costate
# is lx = 0.3 (1 - t) > 0, so H = (u^2 - 1)^2 + 0.3 x + lx u has two wells near u = -1 and u = +1, the one
# at -1 lower by about 2 lx.  Each interval's control lies in a well that is a local minimum of the NLP:
# started in the +1 well, IPOPT stays there (a genuine local optimum, dH/du = 0 with H_uu > 0); only the
# -1 well is the optimum.  The gap at t = 0 is about 2 * 0.3 = 0.6 against terms of size about 0.3.
TWO_WELLS: dict[str, Any] = {"title": "Two wells", "states": [{"name": "x", "initial": 0.0}],
             "controls": [{"name": "u", "lower": -2.0, "upper": 2.0}],
             "time": {"initial": 0.0, "final": 1.0}, "dynamics": {"x": "u"},
             "objective": {"sense": "minimize", "integrand": "(u**2 - 1)**2 + 0.3*x"},
             "transcription": {"method": "multiple_shooting", "intervals": 20, "control": "linear",
                               "substeps": 2}}


def _two_wells(start: float, control: str = "linear"):
    params = {**TWO_WELLS, "transcription": {**TWO_WELLS["transcription"], "control": control},
              "guess": {"controls": {"u": [start, start]}}}
    sol = solve(parse_problem(params))
    assert sol.status.ok
    return sol


@pytest.mark.parametrize("control", ["linear", "constant"])
def test_a_poor_local_optimum_fails_the_minimum_principle_while_stationarity_holds(control):
    """Linear controls are held pointwise, piecewise-constant ones on each interval's average of H."""
    poor, good = _two_wells(1.0, control), _two_wells(-1.0, control)
    assert np.all(np.asarray(poor.trajectory["u"]) > 0.5) and np.all(np.asarray(good.trajectory["u"]) < -0.5)
    assert poor.objective > good.objective + 0.2                        # the +1 well is the worse optimum
    assert poor.status.outcome is Outcome.OPTIMALITY_NOT_VERIFIED and "minimum_principle" in poor.status.message
    assert good.status.outcome is Outcome.OPTIMAL
    checks = poor.verification["optimality"]["checks"]
    if control == "linear":       # stationarity at the nodes is the linear control's condition (B's check)
        assert checks["stationarity"]["held"] and checks["hamiltonian_constant"]["held"]
    mp = checks["minimum_principle"]
    assert not mp["held"] and mp["value"] > 1.0 and mp["t"] == pytest.approx(0.0, abs=0.1)
    assert "minimum_principle" in poor.verification["optimality"]["message"].split("NOT held: ")[1]
    assert good.verification["optimality"]["checks"]["minimum_principle"]["held"]


def test_the_headline_names_the_failed_minimum_principle():
    from app.kinds.ocp import SPEC
    from app.kinds.ocp.headlines import headlines
    from tests.support import RecordingContext

    params = {**TWO_WELLS, "guess": {"controls": {"u": [1.0, 1.0]}}}
    out = SPEC.run(SPEC.params_model.model_validate(params), RecordingContext())
    assert out.result is not None
    assert out.result["verification"]["optimality"]["checks"]["minimum_principle"]["held"] is False
    words = [h.text for h in headlines(out.result, params)]
    assert any(w.startswith("optimality not verified: minimum_principle") for w in words), words
    # stored and served: the job succeeds, its outcome saying the optimum is not verified
    assert out.status == "succeeded" and out.result["solver"]["outcome"] == "optimality_not_verified"


def test_stationarity_holds_on_an_active_path_constraint_with_its_multiplier_in_h():
    """A path constraint that binds (theta <= 1.2 on the last part of the descent): on its arc dH/du = 0
    holds only with mu dc/du in H (mu = the path row's multiplier over the node's trapezoid weight), so the
    arc's nodes are checked too; the minimum principle holds over the admissible set theta <= 1.2."""
    params = {**PRESETS["brachistochrone"]["params"],
              "path": [{"name": "theta_cap", "expr": "theta", "upper": 1.2}]}
    sol = solve(parse_problem(params))
    assert sol.status.ok
    theta = np.asarray(sol.trajectory["theta"])
    on_arc = int(np.sum(theta > 1.2 - 1e-3 * 1.2))
    assert on_arc > 5                                          # the constraint binds
    checks = sol.verification["optimality"]["checks"]
    assert checks["stationarity"]["held"] and checks["stationarity"]["nodes"] > theta.size - on_arc
    assert checks["minimum_principle"]["held"] and checks["hamiltonian_constant"]["held"]


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


# Orbit raising in fixed time (Bryson & Ho, Applied Optimal Control, 1975, sec. 2.5; nondimensional: mu = 1,
# r(0) = 1, thrust 0.1405, mass 1 - 0.0749 t, tf = 3.32): maximise r(tf) on a circular final orbit.  The
# thrust angle phi is bounded by +-10 rad, so it may wrap: started from the default straight-line guess
# (phi = 0), IPOPT stops where phi jumps by more than 2 pi between two nodes, its linear interpolation
# sweeping the thrust through a full turn inside that interval (a local optimum of the NLP, 1.5239); started
# from an unwrapped guess it finds 1.5253, Bryson & Ho's 1.525.
ORBIT: dict[str, Any] = {
    "title": "Orbit raising", "constants": {"T": 0.1405, "mdot": 0.0749},
    "states": [{"name": "r", "initial": 1.0, "lower": 0.5, "upper": 3.0}, {"name": "u", "initial": 0.0},
               {"name": "v", "initial": 1.0}],
    "controls": [{"name": "phi", "lower": -10.0, "upper": 10.0}],
    "time": {"initial": 0.0, "final": 3.32},
    "dynamics": {"r": "u", "u": "v**2/r - 1/r**2 + T*sin(phi)/(1 - mdot*t)",
                 "v": "-u*v/r + T*cos(phi)/(1 - mdot*t)"},
    "boundary": [{"name": "circular_u", "expr": "final(u)", "lower": 0.0, "upper": 0.0},
                 {"name": "circular_v", "expr": "final(v) - sqrt(1/final(r))", "lower": 0.0, "upper": 0.0}],
    "objective": {"sense": "maximize", "expr": "final(r)"},
    "transcription": {"method": "multiple_shooting", "intervals": 40, "control": "linear", "substeps": 2}}


def test_the_poor_orbit_raising_optimum_from_a_straight_line_is_flagged_by_the_minimum_principle():
    poor = solve(parse_problem(ORBIT))
    good = solve(parse_problem({**ORBIT, "guess": {"controls": {"phi": [0.4, 5.3]}}}))
    assert poor.status.solver_status == good.status.solver_status == "Solve_Succeeded"
    assert good.objective == pytest.approx(1.525, abs=1e-3) and good.objective > poor.objective + 1e-3
    assert good.status.outcome is Outcome.OPTIMAL and good.verification["optimality"]["held"]
    assert poor.status.outcome is Outcome.OPTIMALITY_NOT_VERIFIED and poor.verification["ok"]
    mp = poor.verification["optimality"]["checks"]["minimum_principle"]
    assert not mp["held"] and mp["value"] > 5 * mp["tolerance"]
    # the worst gap lies in the interval where phi wraps: the H-minimising angle differs from the swept one
    t, phi = (np.asarray(poor.trajectory[k]) for k in ("t", "phi"))
    k = int(np.searchsorted(t, mp["t"], side="right")) - 1
    assert abs(phi[k + 1] - phi[k]) > np.pi, (mp["t"], phi[k], phi[k + 1])
