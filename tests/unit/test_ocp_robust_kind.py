"""A robust ``ocp`` job run through the kind (``app.kinds.ocp``): the result's ``robust`` block of the contract,
typed by the result model, and ``not_robust`` with the design and its Monte Carlo stored."""
from __future__ import annotations

import copy

from app.kinds.ocp.kind import run
from app.kinds.ocp.params import OcpParams
from app.kinds.ocp.result import OcpResult
from tests.support import RecordingContext
from tests.unit.test_ocp_robust import PUSHED


def _run(body):
    return run(OcpParams.model_validate(body), RecordingContext())


def test_a_confirmed_design_succeeds_with_the_contract_robust_block():
    out = _run(copy.deepcopy(PUSHED))
    assert out.status == "succeeded", out.error
    rob = out.result["robust"]
    assert {"k", "objective", "constraints", "samples", "confirmed"} <= set(rob)
    assert set(rob["objective"]) >= {"mean", "std", "cadet_mean", "cadet_std"}
    assert set(rob["constraints"]["v_max"]) >= {"kept_fraction", "required_fraction"}
    assert rob["confirmed"] is True and rob["samples"] == 2000 and rob["k"] == 2.0
    assert rob["deterministic_objective"] < rob["robust_objective"]
    OcpResult.model_validate(out.result)


def test_a_design_its_monte_carlo_does_not_confirm_fails_not_robust_with_everything_stored():
    body = copy.deepcopy(PUSHED)
    body["robust"]["monte_carlo"].update(sigma_factor=2.0, rounds=0)
    out = _run(body)
    assert out.status == "failed" and out.error["code"] == "not_robust"
    assert "v_max" in out.error["message"]
    assert out.result["robust"]["confirmed"] is False and out.result["trajectory"]["v"]
    OcpResult.model_validate(out.result)
