"""Plots, CSV tables and the report of every preset of every kind, from real solver results."""
from __future__ import annotations

import csv
import io
import math

import numpy as np
import pytest

from app.kinds import KINDS, PRESETS
from app.results import plots as plot_defs
from app.results.report import render_report
from app.results.tables import tables_for, to_csv
from app.summary import key_numbers
from tests.preset_results import solve_preset

FAST = [name for name, p in PRESETS.items() if p.kind != "robust_reentry"]


@pytest.fixture(scope="module")
def solved():
    # solved once per session (tests/preset_results.py), the intercept with its porkchop on
    return {name: solve_preset(name) for name in FAST}


def _check_png(data: bytes, size_in: tuple[float, float]) -> None:
    from matplotlib.image import imread

    img = imread(io.BytesIO(data), format="png")
    assert img.shape[:2] == (round(size_in[1] * 100), round(size_in[0] * 100))
    assert img[..., :3].var() > 1e-3  # not blank


def _check_all(kind: str, params: dict, result: dict) -> list:
    plots = plot_defs.plots_for(kind, result)
    assert plots, kind
    svgs = []
    for p in plots:
        png = plot_defs.render(p, result=result, params=params, title="test", fmt="png")
        _check_png(png, plot_defs.SIZES.get(p.name, (8, 5)))
        svg = plot_defs.render(p, result=result, params=params, title="test", fmt="svg").decode()
        assert "<svg" in svg and "</svg>" in svg
        svgs.append((p.title, svg))
    report = render_report(job={"id": "x" * 32, "kind": kind, "label": "t", "status": "succeeded",
                                "created_at": "c", "finished_at": "f", "params": params},
                           result=result, key_numbers=key_numbers(kind, result), svgs=svgs)
    assert report.count("<svg ") == len(plots)
    for external in ("<script", "<link", 'src="http', "href=\"http", "url(http"):  # self-contained: mailable
        assert external not in report
    for p in plots:
        assert p.title in report
    return plots


@pytest.mark.parametrize("name", FAST)
def test_every_plot_renders_and_the_report_holds_them(solved, name):
    kind, params, outcome = solved[name]
    if outcome.status != "succeeded":  # the paper's infeasible case 4: an answer, with no plots
        assert name == "shuttle-min-heat-load-terminal" and outcome.error["code"] == "infeasible"
        return
    names = [p.name for p in _check_all(kind, params, outcome.result)]
    expected = {"reentry": {"altitude_speed", "ground_track", "controls", "heating"},
                "midcourse": {"pareto_front", "correction_times"},
                "intercept": {"delta_v_scan", "porkchop", "thrust_mass", "hill_trajectory"}}[kind]
    assert set(names) == expected
    if kind == "reentry":  # the re-propagated trajectory is kept and drawn over the solution
        result = outcome.result
        assert len(result["verification"]["trajectory"]["t_s"]) > 10
        heating = next(p for p in plot_defs.plots_for(kind, result) if p.name == "heating")
        without = {**result, "verification": {k: v for k, v in result["verification"].items() if k != "trajectory"}}
        drawn = plot_defs.render(heating, result=result, params=params, title="t", fmt="png")
        assert drawn == plot_defs.render(heating, result=result, params=params, title="t", fmt="png")  # repeatable
        assert drawn != plot_defs.render(heating, result=without, params=params, title="t", fmt="png")


def _num(text: str):
    return None if text == "" else float(text)


@pytest.mark.parametrize("name", FAST)
def test_csv_tables_round_trip_the_json_numbers(solved, name):
    kind, _, outcome = solved[name]
    if outcome.status != "succeeded":
        return
    tables = tables_for(kind, outcome.result)
    assert tables
    for table, cols in tables.items():
        rows = list(csv.reader(io.StringIO(to_csv(cols))))
        assert rows[0] == list(cols) and all(h.rsplit("_", 1)[-1] in (
            "s", "m", "mps", "deg", "kg", "n", "m2", "pa", "factor") for h in rows[0]), rows[0]
        for i, row in enumerate(rows[1:]):
            for h, text in zip(rows[0], row):
                want = cols[h][i]
                got = _num(text)
                if want is None or (isinstance(want, float) and math.isnan(want)):
                    assert got is None or math.isnan(got)
                else:
                    assert got == pytest.approx(want, rel=1e-12, abs=0.0)


@pytest.mark.slow
def test_robust_plots_render():
    _, params, outcome = solve_preset("robust-max-crossrange")  # 2000 samples
    assert outcome.status == "succeeded"
    names = [p.name for p in _check_all("robust_reentry", params, outcome.result)]
    assert {"designs", "envelopes", "terminal_scatter", "heating"} <= set(names)


@pytest.fixture(scope="module")
def finite_intercept():
    _, params, outcome = solve_preset("long-range-intercept")  # both methods: the finite-thrust one is written
    return params, outcome.result


def test_the_oem_reads_back_with_the_library_and_starts_on_the_interceptors_orbit(finite_intercept, tmp_path):
    from oem import OrbitEphemerisMessage

    from app.kinds.intercept import to_problem
    from app.results.oem import has_oem, inertial_states, to_oem
    from solvers.models.relative_motion import circular_state

    params, result = finite_intercept
    assert has_oem("intercept", result) and not has_oem("reentry", {"trajectory": {"t_s": [0.0]}})
    path = tmp_path / "r.oem"
    path.write_text(to_oem(result=result, params=params, object_name="job-1"))
    message = OrbitEphemerisMessage.open(path)
    states = list(message.states)
    t, r, v = inertial_states(result=result, params=params)
    assert len(states) == len(t) > 20
    for s, ri, vi in zip(states, r, v):
        assert s.frame == "EME2000" and s.center == "EARTH"
        np.testing.assert_allclose(s.position * 1e3, ri, rtol=1e-6)
        np.testing.assert_allclose(s.velocity * 1e3, vi, rtol=1e-6)
    # The Hill-to-inertial conversion is right: t0 is exactly the interceptor's initial orbit state.
    typed = KINDS["intercept"].params_model.model_validate(params)
    r0, v0, rt0, vt0 = to_problem(typed).scenario.initial_states()
    assert t[0] == 0.0
    np.testing.assert_allclose(r[0], r0, atol=1e-3)
    np.testing.assert_allclose(v[0], v0, atol=1e-6)
    # and the last state is on the target (interception), within the solver's miss tolerance
    rt, _ = circular_state(r0=rt0, v0=vt0, mu=typed.mu_m3_s2, t=np.array([t[-1]]))
    assert np.linalg.norm(r[-1] - rt[0]) < typed.finite_thrust.miss_tolerance_m


def test_the_default_body_of_the_default_intercept_preset_is_under_50_kb(solved):
    import json

    from app.results.compact import compact

    _, _, outcome = solved["long-range-intercept"]
    # this session solved the preset with the (opt-in) porkchop on; the default preset has none
    result = {**outcome.result, "impulsive": {k: v for k, v in outcome.result["impulsive"].items() if k != "porkchop"}}
    assert set(result) >= {"impulsive", "finite_thrust"}  # both methods, as the preset asks
    size = len(json.dumps(compact("intercept", result, set()), separators=(",", ":")).encode())
    full = len(json.dumps(result, separators=(",", ":")).encode())
    assert size < 50_000 < 400_000 < full, (size, full)
