"""The reentry kind's API edge: parameter rules, presets, run() with a real job context."""
import json
import math

import pytest
from pydantic import ValidationError

from app.kinds.reentry import PRESETS, SPEC, run
from app.kinds.reentry.params import ReentryParams as Params
from app.service.params import deep_merge
from tests.support import RecordingContext


def preset(name, **overrides):
    p = next(p for p in PRESETS if p.name == name)
    return Params.model_validate(deep_merge(p.params, overrides))


@pytest.fixture(scope="module")
def betts():
    ctx = RecordingContext()
    out = run(preset("betts-max-crossrange"), ctx)
    return out, ctx


def test_presets_registered():
    assert SPEC.kind == "reentry"
    assert {p.name for p in PRESETS} == {
        "betts-max-crossrange", "betts-max-crossrange-heat-limited", "shuttle-max-downrange",
        "shuttle-max-crossrange", "shuttle-min-heat-load", "shuttle-min-heat-load-terminal",
        "mars-msl-max-crossrange"}
    for p in PRESETS:
        Params.model_validate(p.params)
    desc = {p.name: p.description for p in PRESETS}
    assert "32.86" in desc["shuttle-min-heat-load-terminal"]
    assert "degenerate" in desc["shuttle-max-downrange"]
    assert "guess" in desc["shuttle-min-heat-load"]


@pytest.mark.parametrize("params, rule", [
    ({"grid": {"intervals": 10**6}}, "max_grid_intervals"),
    ({"bounds": {"alpha_deg": [10.0, 5.0]}}, "lo < hi"),
    ({"bounds": {"bank_deg": [0.0]}}, "lo < hi"),
    ({"vehicle": {"mass_kg": -1.0}}, "greater than 0"),
    ({"path": {"max_heat_rate_w_m2": float("nan")}}, "finite"),
    ({"terminal": {"altitude_m": 90000.0}}, "below initial_state.altitude_m"),
    ({"objective": "max_fun"}, "objective"),
    ({"bogus": 1}, "bogus"),
])
def test_bad_params_name_the_rule(params, rule):
    with pytest.raises(ValidationError) as exc:
        Params.model_validate(params)
    assert rule in str(exc.value)


@pytest.mark.slow
def test_betts_preset_result(betts):
    out, ctx = betts
    assert out.status == "succeeded"
    res = json.loads(json.dumps(out.result, allow_nan=False))
    assert res["solver"]["status"] == "Solve_Succeeded"
    assert res["final"]["latitude_deg"] == pytest.approx(34.1412, abs=1e-3)
    assert res["objective"] == {"name": "max_crossrange", "value": pytest.approx(34.1412, abs=1e-3),
                                "unit": "deg"}
    assert res["tf_s"] == pytest.approx(2008.59, abs=0.5)
    tr = res["trajectory"]
    assert len({len(v) for v in tr.values()}) == 1 and len(tr["t_s"]) == 101
    ver = res["verification"]
    assert abs(ver["final_latitude_diff_deg"]) < 0.01 and abs(ver["final_altitude_diff_m"]) < 30.48
    assert ver["max_heat_rate_w_m2"] >= max(tr["heat_rate_w_m2"]) * (1 - 1e-9)
    dense = ver["trajectory"]   # the re-simulation kept for plots, downsampled
    assert 100 < len(dense["t_s"]) <= 500 and len({len(v) for v in dense.values()}) == 1
    assert dense["t_s"][0] == 0.0 and dense["t_s"][-1] == pytest.approx(res["tf_s"], rel=1e-12)
    assert dense["latitude_deg"][-1] == pytest.approx(res["final"]["latitude_deg"] + ver["final_latitude_diff_deg"],
                                                      abs=1e-9)
    assert max(dense["heat_rate_w_m2"]) <= ver["max_heat_rate_w_m2"] * (1 + 1e-12)
    assert max(dense["heat_rate_w_m2"]) == pytest.approx(ver["max_heat_rate_w_m2"], rel=0.01)
    fr = [f for f, _ in ctx.messages]
    assert fr == sorted(fr) and any("IPOPT iteration" in m for _, m in ctx.messages)
    # the preset's comparison with Betts rides along with the answer
    assert res["notes"][0].startswith("preset betts-max-crossrange: Maximum final latitude.")
    assert "34.1412 deg" in res["notes"][0]


def test_a_preset_is_recognized_by_its_problem_not_by_its_guess():
    from app.kinds.reentry import preset_posed
    for p in PRESETS:
        assert preset_posed(preset(p.name)) is p
        assert preset_posed(preset(p.name, initial_guess={"kind": "linear"})) is p
    assert preset_posed(preset("mars-msl-max-crossrange", grid={"intervals": 60})) is None
    assert preset_posed(preset("betts-max-crossrange", path={"max_heat_rate_w_m2": 700000.0})) is None


@pytest.mark.slow
def test_infeasible_case_fails_with_diagnosis():
    # (how fast it fails is benchmarks' business: IPOPT is told to expect infeasibility)
    out = run(preset("shuttle-min-heat-load-terminal"), RecordingContext())
    assert out.status == "failed"
    assert out.error["code"] == "infeasible"
    assert "Infeasible_Problem_Detected" in out.error["message"]
    assert "latitude" in out.error["message"] and "deg" in out.error["message"]
    # The shortfall is the gap to the 32.86 deg reachable maximum.
    assert "1.14 deg" in out.error["message"]


@pytest.mark.slow
def test_warm_start_from_stored_result(betts):
    out, _ = betts
    stored = json.loads(json.dumps(out.result))
    ctx = RecordingContext(stored={"job-1": stored})
    p = preset("betts-max-crossrange", grid={"intervals": 60}, initial_guess={"from_job": "job-1"})
    warm = run(p, ctx)
    assert warm.status == "succeeded"
    assert warm.result["final"]["latitude_deg"] == pytest.approx(34.1412, abs=2e-3)
    # the warm solve itself; a terminal refinement round may follow at 60 intervals (issue 25)
    assert warm.result["solver"]["stages"][0]["iterations"] <= 15
    assert any("job-1" in n for n in warm.result["notes"])


def test_warm_start_from_unknown_job_is_a_clear_failure():
    from app.kinds.base import JobFailure
    with pytest.raises(JobFailure) as exc:
        run(preset("betts-max-crossrange", initial_guess={"from_job": "nope"}), RecordingContext())
    assert "initial_guess.from_job" in exc.value.message


def test_cancellation_mid_solve():
    ctx = RecordingContext(stop_after=5)
    out = run(preset("betts-max-crossrange", grid={"intervals": 40}), ctx)
    assert out.status == "cancelled"
    assert out.error["code"] == "cancelled"
    assert out.result["solver"]["status"] == "User_Requested_Stop"
    assert out.result["solver"]["iterations"] <= 6


@pytest.mark.slow
def test_paper000_max_crossrange():
    out = run(preset("shuttle-max-crossrange"), RecordingContext())
    assert out.status == "succeeded" and out.result["solver"]["status"] == "Solve_Succeeded"
    assert out.result["final"]["latitude_deg"] == pytest.approx(33.5133, abs=2e-3)
    assert out.result["tf_s"] == pytest.approx(1956.8, abs=1.0)


def test_non_finite_numbers_become_null_not_zero():
    """The one NaN policy (json_float) in the reentry family's result blocks."""
    import numpy as np

    from app.kinds.reentry.edge import final_block, objective_block, trajectory_block
    from solvers.models.reentry_state import Trajectory

    x = np.ones((6, 3))
    x[2, -1] = np.nan
    tr = Trajectory(t=np.array([0.0, 1.0, 2.0]), x=x, u=np.zeros((2, 3)),
                    path={"heat_rate_w_m2": np.array([1.0, np.inf, 2.0])})
    assert objective_block(name="max_crossrange", value=float("nan"), unit="rad") == {
        "name": "max_crossrange", "value": None, "unit": "deg"}
    assert objective_block(name="min_time", value=2000.0, unit="s")["value"] == 2000.0
    assert final_block(tr)["latitude_deg"] is None and final_block(tr)["altitude_m"] == 1.0
    block = trajectory_block(tr)
    assert block["latitude_deg"] == [math.degrees(1.0), math.degrees(1.0), None]
    assert block["heat_rate_w_m2"] == [1.0, None, 2.0]
    json.dumps(block, allow_nan=False)


@pytest.mark.slow
def test_heat_limited_preset_limits_block():
    """Limits that hold: the verification reports each limit's worst fine-grid value and verdict."""
    out = run(preset("betts-max-crossrange-heat-limited"), RecordingContext())
    assert out.status == "succeeded"
    res = json.loads(json.dumps(out.result, allow_nan=False))
    ver = res["verification"]
    assert ver["samples_per_interval"] == 20 and ver["dense_samples"] == 20 * 100 + 1
    lim = ver["limits"]["heat_rate_w_m2"]
    assert lim["limit"] == 794955.0 and lim["tolerance_percent"] == pytest.approx(0.1)
    assert lim["held"] is True and ver["limits_held"] is True
    assert lim["max"] <= 794955.0 * 1.001 and lim["excess_percent"] <= 0.1
    assert lim["max"] == pytest.approx(ver["max_heat_rate_w_m2"], rel=1e-12)
    assert 0.0 <= lim["max_t_s"] <= res["tf_s"]
    assert 0.0 <= ver["error_estimate_altitude_m"] < 0.01 and ver["error_estimate_latitude_deg"] < 1e-6
    assert res["final"]["latitude_deg"] == pytest.approx(30.6255, abs=0.01)
    assert any("hold on the dense re-propagation" in n for n in res["notes"])


@pytest.mark.slow
def test_limit_not_held_fails_with_code_and_stores_the_answer():
    p = preset("betts-max-crossrange-heat-limited", grid={"intervals": 50},
               path={"enforcement": "nodes", "limit_rounds": 0})
    out = run(p, RecordingContext())
    assert out.status == "failed"
    assert out.error["code"] == "limit_not_held"
    assert "heat_rate_w_m2" in out.error["message"] and "limit_rounds 0" in out.error["message"]
    ver = out.result["verification"]        # the best answer, stored as the diagnostic
    assert ver["limits_held"] is False and ver["limits"]["heat_rate_w_m2"]["excess_percent"] > 0.5
    assert out.result["solver"]["status"] == "Solve_Succeeded" and len(out.result["trajectory"]["t_s"]) == 51
