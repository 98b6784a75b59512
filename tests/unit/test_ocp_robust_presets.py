"""Every robust preset of the ``ocp`` kind against its deterministic twin (issue 37 item 5): the twin's optimum, the
robust design confirmed by its Monte Carlo, and the cost of robustness its description states."""
from __future__ import annotations

import copy

import pytest

from solvers.ocp import PRESETS, parse_problem, solve
from solvers.ocp.robust.solver import design_and_confirm
from solvers.uncertainty.montecarlo import run_monte_carlo

# name -> (twin, twin's objective, robust objective, tolerance): the figures of the descriptions on the presets'
# own grids; the tolerance is IPOPT's converged answer on another CPU (1e-4 relative), not a Monte Carlo's noise
CASES = {
    "rocket-ascent-q-limit-robust": ("rocket-ascent-q-limit", 34356.5, 32427.2, 5.0),
    "orbit-raising-uncertain-thrust-robust": ("orbit-raising-band", 1.5446, 1.5207, 2e-4),
}


def test_every_robust_preset_has_a_twin_and_a_case():
    robust = {n for n, p in PRESETS.items() if "uncertainty" in p["params"]}
    assert robust == set(CASES)
    for name, (twin, *_) in CASES.items():
        body = copy.deepcopy(PRESETS[name]["params"])
        body.pop("uncertainty"), body.pop("robust")
        body["title"] = PRESETS[twin]["params"]["title"]
        assert body == PRESETS[twin]["params"], f"{twin} is not {name} without its uncertainty"


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_robust_preset_is_confirmed_by_its_monte_carlo_at_the_stated_cost(name):
    twin, det_value, robust_value, tol = CASES[name]
    det = solve(parse_problem(PRESETS[twin]["params"]))
    assert det.status.ok and det.objective == pytest.approx(det_value, abs=tol)
    body = PRESETS[name]["params"]
    rs, block, _ = design_and_confirm(parse_problem(body), params=body, run_monte_carlo=run_monte_carlo)
    assert rs.solution.status.ok and block["confirmed"] is True
    assert rs.deterministic.objective == pytest.approx(det_value, abs=tol)
    assert rs.solution.objective == pytest.approx(robust_value, abs=tol)
    # the Monte Carlo's spread of the objective is CADET's within 10% (first order, a 1-10% dispersion)
    o = block["objective"]
    assert o["std"] == pytest.approx(o["cadet_std"], rel=0.1)
