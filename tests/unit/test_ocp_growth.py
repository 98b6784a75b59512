"""Dynamics that amplify errors (issue 35 item 5): the answer verified interval by interval from its nodes.

``x' = 2x + u`` over 20 s amplifies any error by e^40 = 2.4e17: a re-flight from t0 departs from every
answer (the NLP's 1e-8 on the nodes alone grows to 2e9), so the check flies each interval from its own
first node (``verification.mode``, with the growth figure and the reason).  The exponent of a linear
system is its eigenvalue times the horizon, exactly.  A problem whose dynamics do not amplify keeps the
flight from t0; so does one with a mild positive eigenvalue (e^1 over the scalar LQ problem's 1 s).
"""
from __future__ import annotations

import copy
import math
import re

from app.kinds.ocp import OcpParams, run
from app.kinds.ocp.headlines import headlines
from solvers.common import Outcome
from solvers.ocp import PRESETS, parse_problem, solve
from solvers.ocp.growth import FROM_T0, INTERVALS, MIN_EXPONENT, NOISE, Growth
from tests.support import RecordingContext

FOREIGN = re.compile(r"heat|reentry|terminal_check|vehicle|monte carlo|k_constraint|grid\.intervals", re.I)


def test_the_mode_switches_where_an_exact_answers_noise_would_pass_the_agreement():
    agreement = 1e-2
    edge = math.log(agreement / NOISE)          # 13.8: e^13.8 * 1e-8 = 1e-2
    assert Growth(exponent=edge * 0.99, max_real_eigenvalue=1.0, duration_s=1.0, agreement=agreement).mode == FROM_T0
    assert Growth(exponent=edge * 1.01, max_real_eigenvalue=1.0, duration_s=1.0, agreement=agreement).mode == INTERVALS
    # an accuracy below the NLP's own tolerance is not the dynamics' doing: no growth, no switch
    assert Growth(exponent=0.0, max_real_eigenvalue=0.0, duration_s=1.0, agreement=1e-9).mode == FROM_T0
    assert Growth(exponent=MIN_EXPONENT * 1.01, max_real_eigenvalue=1.0, duration_s=1.0,
                  agreement=1e-9).mode == INTERVALS


def test_the_unstable_problem_over_20_s_is_verified_interval_by_interval_at_its_closed_form():
    preset = PRESETS["unstable-min-energy"]
    assert preset["params"]["time"]["final"] == 20.0
    sol = solve(parse_problem(preset["params"]))
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    assert sol.status.solver_status == "Solve_Succeeded"
    ver = sol.verification
    assert ver["mode"] == INTERVALS and "own first node" in ver["method"]
    # x' = 2x + u: df/dx = 2 at every node, so G = 2 * 20 exactly (to rounding)
    assert abs(ver["growth"]["exponent"] - 40.0) <= 1e-9 and ver["growth"]["max_real_eigenvalue"] == 2.0
    assert "e^40" in ver["mode_reason"] and "own first node" in ver["mode_reason"]
    # each interval's defect is RK4's local error on h = 0.05 s (~1.5e-7 of the scale), not e^40 of anything
    assert ver["ok"] and ver["agrees"] and ver["max_state_difference_scaled_overall"] < 1e-5, ver["message"]
    assert ver["terminal_held"] and ver["limits_held"]
    assert not sol.solver.get("terminal_refinements") and not sol.solver["limit_rounds"]
    # the closed form 2 / (1 - e^-80) within the preset's grid tolerance (RK4 on 200 intervals: 3e-6 above)
    assert abs(sol.objective - preset["optimum"]) <= preset["tolerance"], sol.objective


def test_a_problem_whose_dynamics_do_not_amplify_is_still_verified_from_t0():
    for name, exponent in (("brachistochrone", 0.0), ("scalar-lq-riccati", 1.0)):
        sol = solve(parse_problem(PRESETS[name]["params"]))
        assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
        ver = sol.verification
        assert ver["mode"] == FROM_T0 and "continuous from the initial state" in ver["method"], name
        assert ver["message"].startswith("re-propagated states agree with the nodes"), ver["message"]
        assert abs(ver["growth"]["exponent"] - exponent) <= 1e-6 * max(1.0, exponent), (name, ver["growth"])
        assert "one flight from t0" in ver["mode_reason"]


def test_an_amplifying_problem_that_fails_is_advised_by_its_own_fields_with_the_growth():
    body = copy.deepcopy(PRESETS["unstable-min-energy"]["params"])
    body["transcription"].update(intervals=10, max_refinements=1)
    body["accuracy"] = 1e-9
    outcome = run(OcpParams.model_validate(body), RecordingContext())
    assert outcome.status == "failed" and outcome.error is not None
    assert outcome.error["code"] == "accuracy_not_reached", outcome.error
    assert outcome.result is not None and outcome.result["verification"]["mode"] == INTERVALS
    advice = outcome.error["details"]["advice"]
    assert "amplify errors by about e^40" in advice[0] and "interval by interval" in advice[0], advice
    assert not any(FOREIGN.search(line) for line in advice), advice
    # the headline says which re-flight it was
    names = [h.name for h in headlines(outcome.result, body)]
    assert "re-flight interval by interval" in names and "re-flight" not in names, names


def test_every_phase_of_an_amplifying_problem_is_verified_interval_by_interval():
    phase = {"states": [{"name": "x"}], "controls": [{"name": "u", "scale": 4.0}], "dynamics": {"x": "a*x + u"},
             "transcription": {"method": "multiple_shooting", "intervals": 100, "control": "linear", "substeps": 2}}
    body = {"constants": {"a": 2.0}, "objective": {"sense": "minimize", "integrand": "0.5*u**2"},
            "phases": [{**copy.deepcopy(phase), "name": "first", "time": {"initial": 0.0, "final": 10.0}},
                       {**copy.deepcopy(phase), "name": "second", "time": {"initial": 10.0, "final": 20.0}}]}
    body["phases"][0]["states"][0]["initial"] = 1.0
    body["phases"][1]["states"][0]["final"] = 0.0
    sol = solve(parse_problem(body))
    assert sol.status.solver_status == "Solve_Succeeded", sol.status.message
    # The second phase's controls are 2e-9 .. 1e-25 (u ~ e^-2t): the optimality check's stationarity, relative
    # to them, reads the multipliers' rounding as 1.5e6 there (solvers/ocp/optimality.py, not the re-flight's
    # matter); everything the re-flight checks is asserted below.
    assert sol.status.outcome in (Outcome.OPTIMAL, Outcome.OPTIMALITY_NOT_VERIFIED), sol.status.message
    assert sol.verification["terminal_held"] and sol.verification["limits_held"]
    # e^20 in each phase: past the threshold e^13.8 on its own
    for ph in sol.phases:
        assert ph["verification"]["mode"] == INTERVALS, ph["name"]
        assert abs(ph["verification"]["growth"]["exponent"] - 20.0) <= 1e-9
    assert sol.verification["mode"] == INTERVALS and sol.verification["ok"] and sol.verification["agrees"]
    # the same grid as the one-phase preset (200 intervals of 0.1 s) and the same closed form
    preset = PRESETS["unstable-min-energy"]
    assert abs(sol.objective - preset["optimum"]) <= preset["tolerance"], sol.objective


def test_accuracy_rounds_on_amplifying_dynamics_reach_the_request_and_return_the_answer():
    """Each round's re-flight error is each interval's own defect (the verification's, not a second flight,
    and not e^40 of it), so the rounds reach the accuracy and the answer is returned, not failed with it
    stored as a partial result."""
    preset = PRESETS["unstable-min-energy"]
    body = copy.deepcopy(preset["params"])
    body["transcription"]["intervals"] = 50
    body["accuracy"] = 1e-4
    sol = solve(parse_problem(body))
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    assert sol.solver["accuracy"]["reached"] and sol.verification["mode"] == INTERVALS
    rounds = sol.solver["refinement"]
    assert len(rounds) >= 2 and all(r["max_error"] < 1e-3 for r in rounds), rounds
    assert sol.verification["max_state_difference_scaled_overall"] <= 1e-4
    # an objective estimated within 1e-4 (relative) of the optimum: the closed form within that
    assert abs(sol.objective - preset["optimum"]) <= 1e-4 * preset["optimum"], sol.objective
