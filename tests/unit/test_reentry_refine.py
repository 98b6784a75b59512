"""The ``reentry`` kind's grid refined to a stated accuracy (issue 26): ``accuracy`` replaces guessing
``grid.intervals``; Betts' shuttle maximum crossrange (34.1412 deg; 34.14118 at 100 intervals,
``shared/specs/reentry.md``) reached from a coarse grid with the reported error under the target."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from solvers import reentry as rs
from solvers.common import Outcome


@pytest.mark.slow
def test_betts_max_crossrange_refined_from_25_intervals():
    # accuracy 1e-6 of each state's scale (0.1 m of altitude at a 1e5 m scale): 25 intervals re-fly
    # to 3e-3, and the objective converges with the grid to 34.1412 deg
    sol = rs.solve(rs.ReentryProblem(intervals=25, accuracy=1e-6))
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    rounds = sol.status.details["refinement"]
    assert len(rounds) >= 2 and rounds[0]["intervals"] == 25 and rounds[0]["max_error"] > 1e-6
    assert rounds[-1]["max_error"] <= 1e-6 and sol.status.details["accuracy_reached"] is True
    assert math.degrees(sol.objective_value) == pytest.approx(34.1412, abs=2e-4)
    # the verification describes the final grid
    assert sol.t.size == rounds[-1]["intervals"] + 1
    from solvers.models.reentry_state import X_SCALE
    assert np.max(sol.verification.max_node_difference / np.asarray(X_SCALE)) == pytest.approx(rounds[-1]["max_error"])
    assert sol.status.iterations == sum(r["iterations"] for r in rounds)
    assert all(s["stage"].startswith("round ") for s in sol.stages)


def test_short_of_the_accuracy_the_reentry_fails_as_accuracy_not_reached():
    sol = rs.solve(rs.ReentryProblem(intervals=20, accuracy=1e-9, max_refinements=0))
    assert sol.status.outcome is Outcome.ACCURACY_NOT_REACHED
    assert "max_refinements" in sol.status.message and sol.t.size == 21


def test_the_reentry_params_carry_the_accuracy_and_cap_the_rounds(monkeypatch):
    from app.kinds.reentry.edge import to_problem
    from app.kinds.reentry.params import ReentryParams

    problem = to_problem(ReentryParams.model_validate({"accuracy": 1e-6, "accuracy_required": False,
                                                       "grid": {"intervals": 25, "max_refinements": 5}}))
    assert (problem.accuracy, problem.accuracy_required, problem.max_refinements) == (1e-6, False, 5)
    assert to_problem(ReentryParams.model_validate({})).accuracy is None
    with pytest.raises(ValidationError, match="TRAJLAB_MAX_GRID_REFINEMENTS"):
        ReentryParams.model_validate({"grid": {"max_refinements": 21}})


def test_robust_reentry_refuses_accuracy_and_refinement_costs_its_rounds():
    from app.kinds.robust_reentry.params import RobustReentryParams
    from app.service.quota import estimate_cost

    with pytest.raises(ValidationError, match="robust_reentry"):
        RobustReentryParams.model_validate({"accuracy": 1e-6})
    assert estimate_cost("reentry", {"accuracy": 1e-6, "grid": {"intervals": 50, "max_refinements": 3}}) == \
        4 * estimate_cost("reentry", {"grid": {"intervals": 50}})
