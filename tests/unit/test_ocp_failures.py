"""An ``ocp`` failure says what happened (issue 35 item 4, issue 38 item 3): the violated entries by their
names with their worst values and times, an overflow from the user's problem as the solver's failure (never
``internal``), and "what to try" from the problem's own fields and transcription, never another kind's.
Real solves through the kind's ``run``, as a worker runs it."""
from __future__ import annotations

import copy
import re

from app.kinds.failures import explain
from app.kinds.ocp import OcpParams, run
from solvers.ocp import PRESETS
from tests.support import RecordingContext

# Words of the other kinds' advice (the reentry heating limit, its terminal_check, the robust kind's
# margins, the grid of the reentry and midcourse kinds): none may reach an ocp job's advice.
FOREIGN = re.compile(r"heat|reentry|terminal_check|vehicle|monte carlo|k_constraint|grid\.intervals", re.I)

# Rao and Mease's hyper-sensitive problem over a long horizon (tf = 10000): the default multiple
# shooting's RK4 steps of 100 s on x' = -x^3 overflow at the straight-line guess, before iteration 1.
HYPERSENSITIVE_LONG = {
    "states": [{"name": "x", "initial": 1.5, "final": 1.0}], "controls": [{"name": "u"}],
    "time": {"initial": 0.0, "final": 10000.0}, "dynamics": {"x": "-x**3 + u"},
    "objective": {"sense": "minimize", "integrand": "0.5*(x**2 + u**2)"},
}

# A double integrator that starts at x = 0 (fixed) under a path entry x >= 1: the entry is violated at
# t = 0 by any trajectory, and the unnamed boundary entry asks more than |u| <= 1 can reach in 1 s.
FLOOR = {
    "states": [{"name": "x", "initial": 0.0}, {"name": "v", "initial": 0.0}],
    "controls": [{"name": "u", "lower": -1.0, "upper": 1.0}],
    "time": {"initial": 0.0, "final": 1.0}, "dynamics": {"x": "v", "v": "u"},
    "path": [{"name": "floor", "expr": "x", "lower": 1.0}],
    "boundary": [{"expr": "final(x)", "lower": 2.0}],
    "objective": {"sense": "minimize", "integrand": "u**2"},
}


def fail(body: dict) -> dict:
    outcome = run(OcpParams.model_validate(body), RecordingContext())
    assert outcome.status == "failed" and outcome.error is not None
    return outcome.error


def test_an_overflowing_guess_is_the_solvers_failure_with_the_methods_advice():
    error = fail(HYPERSENSITIVE_LONG)
    assert error["details"]["solver_status"] == "Invalid_Number_Detected"
    # the user's problem overflowed: a code of its own, not the solver's nor a bug of trajlab's
    assert error["code"] == "numerical_overflow", error
    assert "overflow or NaN at the first guess" in error["message"]
    explained = explain(error)
    assert explained is not None
    advice = " ".join(explained["advice"])
    # a multiple-shooting job is told why its method overflows and which one to use instead
    assert "explicit RK4 steps" in advice and 'transcription.method "lgl"' in advice and "accuracy" in advice
    assert "please report" not in (advice + explained["what"]).lower() and not FOREIGN.search(advice), advice


def test_an_infeasible_problem_names_its_entries_their_worst_values_and_times():
    error = fail(FLOOR)
    assert error["code"] == "infeasible"
    message = error["message"]
    assert "worst constraint violation" not in message
    assert "path constraint 'floor' is 0 at t = 0, asked >= 1" in message, message
    assert "boundary constraint 'boundary[0]'" in message and "asked >= 2" in message, message
    found = {v["name"]: v for v in error["details"]["violations"]}
    assert found["floor"]["value"] == 0.0 and found["floor"]["t"] == 0.0      # x(0) = 0 is a fixed bound
    # the last iterate of an infeasible solve need not fly (its defects are open), but it stops short of 2
    assert found["boundary[0]"]["value"] < 2.0 and found["boundary[0]"]["t"] is None
    explained = explain(error)
    assert explained is not None
    advice = " ".join(explained["advice"])
    assert "floor" in advice and not FOREIGN.search(advice), advice


def test_an_unnamed_entry_of_a_later_phase_is_named_by_its_field_path_and_phase():
    body = copy.deepcopy(PRESETS["goddard-three-phases"]["params"])
    phase = body["phases"][1]
    assert not phase.get("path")          # so the entry added is path[0] of phase 1
    phase["path"] = [{"expr": phase["states"][0]["name"], "lower": 1e6}]     # far above any value it takes
    error = fail(body)
    assert error["code"] == "infeasible"
    assert f"path constraint 'phases[1].path[0]' in phase {phase['name']} is " in error["message"], error["message"]
    worst = error["details"]["violations"][0]
    assert worst["name"] == "phases[1].path[0]" and worst["phase"] == phase["name"] and worst["value"] < 1e6
