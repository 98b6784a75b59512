"""A failed job's code names what failed (issue 34 item 5): a solver's own failure is `solver_failed` and a
user's unusable warm-start reference `invalid_input`, never `internal` (the code of a fault of trajlab
itself, e.g. a worker that raised); tests/unit/test_error_codes.py holds the codes to their one declaration."""
from __future__ import annotations

import pytest

from app.kinds import KINDS, PRESETS
from app.kinds.base import InProcessContext, JobFailure
from app.service.params import resolve_params


def test_an_overflow_of_the_users_problem_is_numerical_overflow_not_internal():
    # sqrt of a state that starts at -1: IPOPT meets NaN at its first evaluation (a real solve, no mock)
    params = resolve_params(KINDS["ocp"], None, {
        "states": [{"name": "x", "initial": -1.0, "final": 1.0}],
        "controls": [{"name": "u", "lower": -1.0, "upper": 1.0}],
        "time": {"initial": 0.0, "final": 2.0}, "dynamics": {"x": "sqrt(x) + u"},
        "objective": {"sense": "minimize", "integrand": "u**2"}, "transcription": {"intervals": 10}})
    spec = KINDS["ocp"]
    outcome = spec.run(spec.params_model.model_validate(params), InProcessContext())
    assert outcome.status == "failed"
    assert outcome.error["code"] == "numerical_overflow"   # the user's numbers (issue 35 item 4), not a bug
    assert outcome.error["details"]["solver_status"] == "Invalid_Number_Detected"


def test_an_unusable_warm_start_reference_is_invalid_input():
    spec = KINDS["reentry"]
    params = resolve_params(spec, PRESETS["betts-max-crossrange"].params,
                            {"initial_guess": {"from_job": "f" * 32}})
    with pytest.raises(JobFailure) as failure:  # deleted since the door checked it: nothing stored
        spec.run(spec.params_model.model_validate(params), InProcessContext())
    assert failure.value.code == "invalid_input" and "initial_guess.from_job" in failure.value.message
    with pytest.raises(JobFailure) as failure:  # a stored result without a trajectory
        spec.run(spec.params_model.model_validate(params), InProcessContext(stored={"f" * 32: {"objective": 1}}))
    assert failure.value.code == "invalid_input"

