"""Several starts (``search: {"starts": N}``, issue 35 item 3): real solves through the kind's ``run`` (the
starts one after the other, as a job without other workers runs them; tests/integration/test_ocp_starts_http.py
fans them out).

The case with two local optima is analytically known: x' = u, |u| <= 4, x(0) = 0 on [0, 1], minimize
int u^2/2 dt - 3 exp(-(x(1) - 2)^2 / 0.5) (a well at x = 2).  For a given x(1) = x1, the least
int u^2/2 with int u = x1 is x1^2/2 (u constant, Cauchy-Schwarz), so the problem is the scalar
J(x1) = x1^2/2 - 3 exp(-(x1 - 2)^2 / 0.5): a local minimum near x1 = 0.008 (the well's tail) with J ~ -0.001,
and the global one near x1 = 1.83 with J ~ -1.157.  The transcription is exact for it (linear controls
hold a constant, RK4 integrates x' = u and u^2 exactly), so the NLP's optima are J's to IPOPT's tolerance.
The straight-line guess (u = 0, the middle of its bounds; x = 0) lies in the first basin.
"""
from __future__ import annotations

import pytest
from pydantic import ValidationError
from scipy.optimize import minimize_scalar

from app.kinds.ocp import OcpParams, run
from app.kinds.ocp.kind import cost
from solvers.ocp.starts import RULE, distinct_optima, start_guess
from tests.support import RecordingContext

WELL = {
    "states": [{"name": "x", "initial": 0.0}], "controls": [{"name": "u", "lower": -4.0, "upper": 4.0}],
    "time": {"initial": 0.0, "final": 1.0}, "dynamics": {"x": "u"},
    "objective": {"sense": "minimize", "expr": "-3*exp(-(final(x) - 2)**2/0.5)", "integrand": "0.5*u**2"},
    "transcription": {"intervals": 10},
}
# sqrt(x(1) + 0.25) is undefined below x(1) = -0.25: a start whose control level is in the lowest third of
# [-2, 2] flies there (x(1) = level <= -2/3, re-scaled by at least 1/2) and overflows at its guess, the
# flown guess too; the others find the one optimum
ROOT = {
    "states": [{"name": "x", "initial": 0.0}], "controls": [{"name": "u", "lower": -2.0, "upper": 2.0}],
    "time": {"initial": 0.0, "final": 1.0}, "dynamics": {"x": "u"},
    "objective": {"sense": "minimize", "expr": "-sqrt(final(x) + 0.25)", "integrand": "0.5*u**2"},
    "transcription": {"intervals": 10},
}


def J(x1: float) -> float:
    import math
    return 0.5 * x1**2 - 3.0 * math.exp(-(x1 - 2.0) ** 2 / 0.5)


def local_minima() -> tuple[float, float]:
    near = minimize_scalar(J, bounds=(-1.0, 0.6), method="bounded", options={"xatol": 1e-12})
    far = minimize_scalar(J, bounds=(1.0, 3.0), method="bounded", options={"xatol": 1e-12})
    return near.fun, far.fun


def solve(body: dict):
    return run(OcpParams.model_validate(body), RecordingContext())


def test_the_default_guess_finds_the_worse_optimum_and_five_starts_the_better():
    worse, better = local_minima()
    assert worse == pytest.approx(-0.00104, abs=1e-5) and better == pytest.approx(-1.1575, abs=1e-4)
    one = solve(WELL)
    assert one.status == "succeeded" and "search" not in one.result
    assert one.result["objective"]["value"] == pytest.approx(worse, rel=1e-7, abs=1e-10)

    out = solve({**WELL, "search": {"starts": 5}})
    assert out.status == "succeeded"
    result, search = out.result, out.result["search"]
    assert result["objective"]["value"] == pytest.approx(better, rel=1e-7)
    assert result["final"]["x"] == pytest.approx(minimize_scalar(J, bounds=(1.0, 3.0), method="bounded",
                                                                 options={"xatol": 1e-12}).x, rel=1e-6)
    assert search["starts"] == 5 and search["succeeded"] == 5 and search["rule"] == RULE
    assert search["best_start"] != 0 and search["seed"] == 0
    optima = search["distinct_optima"]
    assert [o["objective"] for o in optima] == [pytest.approx(better, rel=1e-7), pytest.approx(worse, rel=1e-6)]
    assert sum(o["count"] for o in optima) == 5
    assert [e["start"] for e in search["each"]] == list(range(5))
    assert search["each"][0]["objective"] == pytest.approx(worse, rel=1e-6)     # start 0 is the given guess
    assert result["notes"][0].startswith("best of 5 starts")
    from app.kinds.ocp.headlines import headlines
    texts = [h.text for h in headlines(result, {**WELL, "search": {"starts": 5}})]
    assert f"starts: best of 5 (start {search['best_start']}), 5 succeeded, 2 distinct optima" in texts, texts


def test_the_starts_are_deterministic_and_spread_the_controls_over_their_bounds():
    problem = OcpParams.model_validate({**WELL, "search": {"starts": 5}}).problem
    assert start_guess(problem, index=0, starts=5, seed=0) is None           # the problem's own straight lines
    levels = []
    for k in range(1, 5):
        a = start_guess(problem, index=k, starts=5, seed=0)
        b = start_guess(problem, index=k, starts=5, seed=0)
        assert a == b and a is not None
        u = a["trajectory"]["u"]
        assert min(u) == max(u)                                                 # one level per start
        levels.append(u[0])
        assert a["trajectory"]["x"][0] == 0.0                                   # the fixed initial value kept
    # one level in each quarter of [-4, 4]
    assert sorted(int((v + 4.0) // 2.0) for v in levels) == [0, 1, 2, 3]
    other = start_guess(problem, index=1, starts=5, seed=1)
    assert other is not None and other["trajectory"]["u"][0] != levels[0]


def test_one_failing_start_does_not_fail_the_job():
    out = solve({**ROOT, "search": {"starts": 4}})
    assert out.status == "succeeded"
    search = out.result["search"]
    failed = [e for e in search["each"] if e["status"] == "failed"]
    assert len(failed) == 1 and failed[0]["code"] == "numerical_overflow" and failed[0]["objective"] is None
    assert search["succeeded"] == 3 and len(search["distinct_optima"]) == 1
    assert search["distinct_optima"][0]["count"] == 3


def test_every_start_failing_fails_the_job_with_the_closest_diagnostic():
    body = {**ROOT, "objective": {"sense": "minimize", "expr": "-sqrt(final(x) - 5)", "integrand": "0.5*u**2"},
            "search": {"starts": 3}}                     # x(1) <= 2 < 5: sqrt is undefined at every start
    out = solve(body)
    assert out.status == "failed" and out.error["code"] == "numerical_overflow"
    assert out.error["message"].startswith("all 3 starts failed; start ")
    search = out.error["details"]["search"]
    assert search["succeeded"] == 0 and search["distinct_optima"] == [] and len(search["each"]) == 3


def test_starts_past_the_setting_are_a_422_naming_it_and_each_start_costs():
    with pytest.raises(ValidationError) as exc:
        OcpParams.model_validate({**WELL, "search": {"starts": 17}})
    error = exc.value.errors()[0]
    assert error["loc"] == ("search", "starts")
    assert "17 starts exceed the limit max_starts=16" in error["msg"] and "TRAJLAB_OCP_MAX_STARTS" in error["msg"]
    assert cost({**WELL, "search": {"starts": 4}}) == pytest.approx(4 * cost(WELL))


def test_several_phases_start_from_varied_guesses_too():
    # the two-stage ascent (app preset two-stage-ascent): every start reaches the closed-form apogee
    from solvers.ocp import PRESETS

    case = PRESETS["two-stage-ascent"]
    out = solve({**case["params"], "search": {"starts": 2}})
    assert out.status == "succeeded", out.error
    search = out.result["search"]
    assert search["succeeded"] == 2 and len(search["distinct_optima"]) == 1
    assert out.result["objective"]["value"] == pytest.approx(case["optimum"], abs=case["tolerance"])


def test_several_starts_of_a_robust_design_are_refused_naming_the_field():
    from solvers.ocp import OcpInputError, parse_problem
    from tests.unit.test_ocp_robust import LINEAR

    with pytest.raises(OcpInputError) as exc:
        parse_problem({**LINEAR, "search": {"starts": 2}})
    assert exc.value.path == "params.search.starts" and "initial_guess.from_job" in exc.value.reason


def test_distinct_optima_group_within_the_tolerance():
    groups = distinct_optima([1.0, 1.0 + 1e-7, 2.0, 0.5, float("nan")], tolerance=1e-5, sense="minimize")
    assert groups == [{"objective": 0.5, "count": 1}, {"objective": 1.0, "count": 2}, {"objective": 2.0, "count": 1}]
    assert distinct_optima([1.0, 2.0], tolerance=1e-5, sense="maximize")[0]["objective"] == 2.0
