"""The midcourse kind's API edge: parameter rules, presets, run() with a job context."""
import json

import pytest
from pydantic import ValidationError

from app.kinds.midcourse import PRESETS, SPEC, run
from app.kinds.midcourse.params import MidcourseParams
from app.service.params import deep_merge
from tests.support import RecordingContext


def preset(name, **overrides):
    p = next(p for p in PRESETS if p.name == name)
    return MidcourseParams.model_validate(deep_merge(p.params, overrides))


def test_spec_and_presets():
    assert SPEC.kind == "midcourse"
    names = {p.name for p in PRESETS}
    assert "upper-stage-two-corrections" in names
    two = preset("upper-stage-two-corrections")
    assert (two.mode, two.corrections, two.population, two.generations) == ("optimize", 2, 100, 500)
    assert (two.crossover_prob, two.mutation_prob, two.time_bounds_s) == (0.8, 0.1, [0.0, 12800.0])
    desc = next(p for p in PRESETS if p.name == "upper-stage-two-corrections").description
    assert "0.5 m/s" in desc and "330 m" in desc and "261 m" in desc and "late second" in desc


@pytest.mark.parametrize("params, rule", [
    ({"corrections": 6}, "corrections"),
    ({"corrections": 0}, "corrections"),
    ({"population": 3}, "population"),
    ({"population": 10**6}, "population"),
    ({"generations": 10**6}, "generations"),
    ({"mode": "evaluate"}, "at least one schedule"),
    ({"mode": "evaluate", "schedules": [[8000.0, 3000.0]]}, "sorted"),
    ({"mode": "evaluate", "schedules": [[13000.0]]}, "within [0, tf_s)"),
    ({"mode": "evaluate", "schedules": [[-1.0]]}, "within [0, tf_s)"),
    ({"mode": "evaluate", "schedules": [[1, 2, 3, 4, 5, 6]]}, "at most 5"),
    ({"mode": "evaluate", "schedules": [[1000.0, 1500.0]], "min_spacing_s": 1000.0}, "min_spacing_s apart"),
    ({"time_bounds_s": [5000.0, 4000.0]}, "earliest < latest"),
    ({"time_bounds_s": [0.0, 13000.0]}, "before tf_s"),
    ({"corrections": 5, "min_spacing_s": 4000.0}, "min_spacing_s too large"),
    ({"initial": {"position_m": [1.0, 2.0]}}, "position_m"),
    ({"initial_error": {"velocity_mps": [float("nan"), 0.0, 0.0]}}, "velocity_mps"),
    ({"dispersion": {"samples": 1000}, "population": 1000}, "population * dispersion.samples"),
    ({"frame": "ecef"}, "frame"),
    ({"bogus": 1}, "bogus"),
])
def test_bad_params_name_the_rule(params, rule):
    with pytest.raises(ValidationError) as exc:
        MidcourseParams.model_validate(params)
    assert rule in str(exc.value)


def test_table3_preset_runs_and_is_json():
    ctx = RecordingContext()
    out = run(preset("upper-stage-table3"), ctx)
    assert out.status == "succeeded"
    res = json.loads(json.dumps(out.result, allow_nan=False))
    rows = res["schedules"]
    assert [r["times_s"] for r in rows][3] == [3000.0, 8000.0]
    assert rows[4]["delta_v_mps"] == pytest.approx(32.004, abs=0.5)
    assert rows[4]["velocity_error_mps"] == pytest.approx(4.315, abs=0.5)
    assert rows[4]["position_error_m"] == pytest.approx(337.5, abs=2.0)
    assert all(r["lambert_converged"] for r in rows)
    assert len(rows[6]["impulses_mps"]) == 3
    assert res["pareto_front"] and 0.0 < res["hypervolume"] <= 1.0
    assert res["notes"] and "261 m" in res["notes"][0]
    assert ctx.messages[-1] == (1.0, "schedule 7/7")


def test_small_optimize_run_result():
    ctx = RecordingContext()
    out = run(preset("upper-stage-two-corrections", population=12, generations=6, seed=5), ctx)
    assert out.status == "succeeded"
    res = json.loads(json.dumps(out.result, allow_nan=False))
    assert res["generations"] == 6 and res["seed"] == 5 and res["evaluations"] >= 12 * 6
    assert res["settings"]["population"] == 12
    assert res["schedules"] is None
    for p in res["pareto_front"]:
        assert len(p["times_s"]) == 2 and p["times_s"][0] <= p["times_s"][1]
        assert set(p) >= {"delta_v_mps", "position_error_m", "velocity_error_mps"}
    assert ctx.messages[-1] == (1.0, "generation 6/6")


def test_cancelled_run_keeps_a_partial_front():
    out = run(preset("upper-stage-two-corrections", population=12, generations=50), RecordingContext(stop_after=2))
    assert out.status == "cancelled"
    assert out.result["generations"] == 2
    assert out.result["pareto_front"]
    assert out.error["code"] == "cancelled"


def test_monte_carlo_result_has_both_statistics():
    out = run(preset("upper-stage-table3", schedules=[[1000.0, 8000.0]],
                     dispersion={"samples": 50, "percentile": 95.0, "seed": 2}), RecordingContext())
    assert out.status == "succeeded"
    row = out.result["schedules"][0]
    assert row["percentile"]["position_error_m"] > row["mean"]["position_error_m"]
    assert row["delta_v_mps"] == row["percentile"]["delta_v_mps"]
    assert "impulses_mps" not in row


def test_monte_carlo_optimize_reports_both_statistics_on_the_front():
    out = run(preset("upper-stage-two-corrections", population=8, generations=3,
                     dispersion={"samples": 10, "percentile": 90.0, "statistic": "mean"}), RecordingContext())
    assert out.status == "succeeded"
    res = json.loads(json.dumps(out.result, allow_nan=False))
    assert res["settings"]["objectives"] == "mean"
    for p in res["pareto_front"]:
        assert p["delta_v_mps"] == pytest.approx(p["mean"]["delta_v_mps"], rel=1e-12)
        assert set(p["percentile"]) == {"delta_v_mps", "position_error_m", "velocity_error_mps"}
        assert p["percentile"]["position_error_m"] > 0.0


_PAPER_RUN_CHILD = """
import json, sys
from tests.unit.test_midcourse_kind import preset, run, RecordingContext
res = run(preset("upper-stage-two-corrections"), RecordingContext()).result
front = res["pareto_front"]
json.dump({"hypervolume": res["hypervolume"],
           "points": [[p["times_s"], p["delta_v_mps"], p["position_error_m"], p["velocity_error_mps"]]
                      for p in front]}, sys.stdout)
"""


@pytest.mark.slow
def test_paper_run_front_is_the_same_in_another_process_and_as_good_as_the_seeds_spread():
    # Paper 002's preset (100 x 500, seed 1).  A genetic search follows roundoff and its random
    # stream, so its front is not a reference number (Table 3's are, in test_midcourse.py), and its
    # last bits are the machine's: numba and heyoka compile for the host CPU, so the same commit
    # gave hypervolume 0.74322 on one machine and 0.77044 on another.  Two things hold anywhere:
    # 1. the same seed gives the same front bit for bit in another process (a case's bits once
    #    depended on its place in a vectorized batch: e2da9a7);
    # 2. the front is as good as NSGA-II's spread over seeds: seeds 1-3 here and on pymoo's own
    #    implementation gave 0.729-0.787 (commit 011a588 and issue 16's Lambert change).
    import subprocess
    import sys
    from pathlib import Path

    out = run(preset("upper-stage-two-corrections"), RecordingContext())
    res = out.result
    assert out.status == "succeeded" and res["generations"] == 500 and res["evaluations"] == 50000
    front = res["pareto_front"]
    assert len(front) == 100
    assert 0.72 <= res["hypervolume"] <= 0.80
    # the cheapest point costs about 20 m/s with errors of tens of km; the most accurate lands
    # within a metre at a few hundred m/s
    assert front[0]["delta_v_mps"] < 25.0
    assert min(p["position_error_m"] for p in front) < 1.0
    child = subprocess.run([sys.executable, "-c", _PAPER_RUN_CHILD], capture_output=True, text=True,
                           cwd=Path(__file__).resolve().parents[2], timeout=300, check=True)
    other = json.loads(child.stdout)
    assert other["hypervolume"] == res["hypervolume"]
    assert other["points"] == [[p["times_s"], p["delta_v_mps"], p["position_error_m"], p["velocity_error_mps"]]
                               for p in front]
    # the default spacing holds on the whole front
    assert min(p["times_s"][1] - p["times_s"][0] for p in front) >= 60.0 - 1e-9
    assert SPEC.key_numbers(res) == {"front_size": 100, "hypervolume": res["hypervolume"],
                                     "min_delta_v_mps": front[0]["delta_v_mps"],
                                     "min_position_error_m": min(p["position_error_m"] for p in front),
                                     "generations": 500}
