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
from app.service.summary import key_numbers
from tests.preset_results import solve_preset
from solvers.uncertainty.montecarlo import MAX_TERMINAL_SAMPLES

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
        _check_png(png, p.size)
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
@pytest.mark.slow
def test_every_plot_renders_and_the_report_holds_them(solved, name):
    kind, params, outcome = solved[name]
    if outcome.status != "succeeded":  # the paper's infeasible case 4: an answer, with no plots
        assert name == "shuttle-min-heat-load-terminal" and outcome.error["code"] == "infeasible"
        return
    names = [p.name for p in _check_all(kind, params, outcome.result)]
    if kind == "ocp":  # every state, control and expression against time, then the pairs asked for
        trajectories = [p["trajectory"] for p in outcome.result.get("phases") or [outcome.result]]
        quantities = {n for tr in trajectories for n in tr if n != "t"}
        expected = {f"t-{n}" for n in quantities} | {f"{x}-{y}" for x, y in params["plots"]}
        if params.get("robust"):   # a robust design: its Monte Carlo's envelopes and histograms (issue 37 item 4)
            named = set(params["robust"]["constraints"])
            expected |= {f"mc-state-{s['name']}" for s in params["states"]} | {"mc-objective"}
            expected |= {f"mc-constraint-{c['name']}" for c in params.get("path") or [] if c["name"] in named}
            expected |= {f"mc-boundary-{c['name']}" for c in params.get("boundary") or [] if c["name"] in named}
    else:
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
@pytest.mark.slow
def test_csv_tables_round_trip_the_json_numbers(solved, name):
    kind, _, outcome = solved[name]
    if outcome.status != "succeeded":
        return
    tables = tables_for(kind, outcome.result)
    assert tables
    for table, cols in tables.items():
        rows = list(csv.reader(io.StringIO(to_csv(cols))))
        assert rows[0] == list(cols)
        if table.startswith("robust_"):   # a robust design's Monte Carlo: its own columns, numbers round-trip
            robust = outcome.result["robust"]
            n = {"robust_envelope": len(robust["monte_carlo"]["envelope"]["t"]),
                 # the first MAX_TERMINAL_SAMPLES draws are kept (the shuttle flies 10,000)
                 "robust_samples": min(robust["samples"], MAX_TERMINAL_SAMPLES),
                 "robust_rounds": len(robust["rounds"])}[table]
            assert len(rows) == 1 + n
            for i, row in enumerate(rows[1:]):
                for h, text in zip(rows[0], row):
                    want = cols[h][i]
                    assert text == str(want) if isinstance(want, bool) else \
                        _num(text) == pytest.approx(want, rel=1e-12, abs=0.0), (table, h, i)
            continue
        if kind == "ocp" and outcome.result.get("phases"):  # several phases stacked, a phase column first
            names = {n for p in outcome.result["phases"] for n in p["trajectory"]}
            assert rows[0][:2] == ["phase", "t"] and set(rows[0][1:]) <= names, rows[0]
            assert {r[0] for r in rows[1:]} == {p["name"] for p in outcome.result["phases"]}
            continue
        if kind == "ocp":  # the problem's own names: t and what it declared (units its own, in result.units)
            assert rows[0][0] == "t" and set(rows[0]) <= set(outcome.result["trajectory"]), rows[0]
        else:
            assert all(h.rsplit("_", 1)[-1] in (
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
    from app.kinds.intercept.oem import inertial_states, to_oem
    from app.kinds import KINDS
    from solvers.models.relative_motion import circular_state

    params, result = finite_intercept
    assert KINDS["intercept"].oem.available(result) and KINDS["reentry"].oem is None
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


@pytest.mark.slow
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


def _read_oem(text: str, tmp_path):
    from oem import OrbitEphemerisMessage

    path = tmp_path / "m.oem"
    path.write_text(text)
    return OrbitEphemerisMessage.open(path)


def test_the_midcourse_oem_reads_back_and_flies_the_front_points_corrections(tmp_path):
    from app.kinds.midcourse import to_problem
    from app.kinds.midcourse.oem import default_point, midcourse_segments, midcourse_to_oem
    from solvers.midcourse.trajectory import inertial_rotation

    _, params, outcome = solve_preset("upper-stage-table3")
    result = outcome.result
    front = result["pareto_front"]
    problem = to_problem(KINDS["midcourse"].params_model.model_validate(params))
    m = inertial_rotation(problem.frame)
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(m @ problem.frame.spin_axis, [0, 0, 1], atol=1e-15)  # z: the spin axis
    assert abs((m @ problem.frame.r0)[1]) < 1e-6  # the launch point lies in the x-z plane (its meridian)
    r_target = m @ (problem.r_target + problem.frame.r0)
    i = next(k for k, p in enumerate(front) if len(p["times_s"]) == 3)  # (1000, 5000, 8000) s
    point = front[i]
    message = _read_oem(midcourse_to_oem(result=result, params=params, object_name="job-1", point=i), tmp_path)
    segments, comments = midcourse_segments(result=result, params=params, point=i)
    assert len(message.segments) == len(segments) == 4 and "launch meridian" in comments[2]
    for seg, (t, r, v) in zip(message.segments, segments):
        assert seg.metadata["REF_FRAME"] == "EME2000" and seg.metadata["CENTER_NAME"] == "EARTH"
        states = list(seg.states)
        assert len(states) == len(t) >= 2
        for s, ri, vi in zip(states, r, v):  # what was written is what the library reads, to 1e-6
            np.testing.assert_allclose(s.position * 1e3, ri, rtol=1e-6)
            np.testing.assert_allclose(s.velocity * 1e3, vi, rtol=1e-6)
    # the flight is the front point's: it starts from the erroneous initial state, each boundary is
    # one of the stored impulses (position continuous, velocity jumps by it), and it lands with the
    # point's position and velocity errors
    t0, r0, v0 = segments[0][0][0], segments[0][1][0], segments[0][2][0]
    assert t0 == 0.0
    np.testing.assert_allclose(r0, m @ (problem.r0 + problem.frame.r0 + problem.position_error), rtol=1e-12)
    np.testing.assert_allclose(v0, m @ (problem.v0 + problem.velocity_error), rtol=1e-12)
    for k, impulse in enumerate(point["impulses_mps"]):
        (ta, ra, va), (tb, rb, vb) = segments[k], segments[k + 1]
        assert ta[-1] == tb[0] == point["times_s"][k]
        np.testing.assert_allclose(ra[-1], rb[0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(vb[0] - va[-1], m @ np.asarray(impulse), rtol=0, atol=1e-9)
    t_end, r_end, v_end = segments[-1][0][-1], segments[-1][1][-1], segments[-1][2][-1]
    assert t_end == params["tf_s"]
    assert np.linalg.norm(r_end - r_target) == pytest.approx(point["position_error_m"], rel=1e-6)
    assert np.linalg.norm(v_end - m @ problem.v_target) == pytest.approx(point["velocity_error_mps"], rel=1e-6)
    # the default is the point of least delta-v (here no correction: the uncorrected coast, one segment)
    assert default_point(result) == int(np.argmin([p["delta_v_mps"] for p in front]))
    # the nominal transfer lands within the nominal's own miss of the target
    nominal, _ = midcourse_segments(result=result, params=params, point=i, trajectory="nominal")
    assert len(nominal) == 1 and nominal[0][0][-1] == params["tf_s"]
    assert np.linalg.norm(nominal[0][1][-1] - r_target) == pytest.approx(result["nominal_miss"]["position_m"], rel=1e-6)


def test_the_midcourse_oem_route_picks_a_point_and_the_index_lists_it(tmp_path):
    from fastapi.testclient import TestClient

    from app.service import jobs
    from app.runtime.db import get_database
    from app.api.main import create_app
    from app.runtime.migrate import upgrade
    from app.runtime.settings import Settings

    url = f"sqlite:///{tmp_path / 'r.db'}"
    upgrade(url)
    db = get_database(url)
    kind, params, outcome = solve_preset("upper-stage-two-corrections")
    job, _ = jobs.create_job(db, kind=kind, params=params, label="mc", preset=None)
    claim = jobs.claim(db, job.id, job.attempts, worker="t", max_attempts=3, stale_after_s=60)
    assert jobs.finish(db, job.id, claim.attempt, status="succeeded", result=outcome.result, error=None, message="ok")
    db.dispose()
    front = outcome.result["pareto_front"]
    with TestClient(create_app(Settings(database_url=url, broker_url="redis://127.0.0.1:1/0"))) as client:
        assert client.get(f"/v1/jobs/{job.id}/plots").json()["oem"] == f"/v1/jobs/{job.id}/result.oem"
        default = client.get(f"/v1/jobs/{job.id}/result.oem")
        assert default.status_code == 200 and default.headers["content-type"].startswith("application/ccsds-oem")
        best = int(np.argmin([p["delta_v_mps"] for p in front]))
        assert f"OBJECT_NAME = mc point {best}\n" in default.text
        last = client.get(f"/v1/jobs/{job.id}/result.oem", params={"point": len(front) - 1})
        assert last.status_code == 200 and f"mc point {len(front) - 1}" in last.text and last.text != default.text
        assert client.get(f"/v1/jobs/{job.id}/result.oem", params={"point": len(front)}).status_code == 404
        nominal = client.get(f"/v1/jobs/{job.id}/result.oem", params={"trajectory": "nominal"})
        assert nominal.status_code == 200 and "OBJECT_NAME = mc nominal" in nominal.text
        message = _read_oem(last.text, tmp_path)
        point = front[-1]
        coasts = len({t for t in point["times_s"] if 0 < t < params["tf_s"]}) + 1
        assert len(message.segments) == coasts
        again = client.get(f"/v1/jobs/{job.id}/result.oem", params={"point": len(front) - 1},
                           headers={"If-None-Match": last.headers["etag"]})
        assert again.status_code == 304
