"""The panels of a study's plot (issue 38 item 5): the swept value against the outputs that vary, with
units from the kind's declarations; counts and booleans in the table only; no axis offset.

Each study's points are real solves (the kind's ``run``, as a worker calls it) assembled into the rows
``app.service.studies.trade_table`` builds; the chart is read as a panel description and as matplotlib
figure objects, never as pixels.
"""
from __future__ import annotations

import math

import pytest

from app.kinds import KINDS, PRESETS
from app.kinds.trade import name_label, name_unit
from app.results.study_plot import draw
from app.service.params import resolve_params
from app.service.study_chart import chart
from app.service.studies import expand
from tests.support import RecordingContext

G0 = 9.80665


def _study(preset: str, overrides: dict, sweeps: list[dict]):
    """(rows, first result, first params) of a study of ``preset`` solved point by point."""
    spec = KINDS[PRESETS[preset].kind]
    base = resolve_params(spec, PRESETS[preset].params, overrides)
    rows, first = [], None
    for point in expand(base, sweeps):
        params = resolve_params(spec, None, point.params)
        out = spec.run(spec.params_model.model_validate(params), RecordingContext())
        row = {"index": point.index, **point.values, "status": out.status, "job_id": None, "jobs": 1}
        if out.status == "succeeded":
            row.update(spec.key_numbers(out.result))
            first = first or (out.result, params)
        rows.append(row)
    return spec, rows, first


def _drawn(c):
    fig = draw(c)
    fig.canvas.draw()      # tick labels and offset texts exist only once drawn
    return fig.axes


def _no_offset(ax, *, x_labelled: bool) -> None:
    """No offset or power of ten in a corner, and plain tick labels (the shared x axis is labelled on the
    bottom panel only)."""
    for axis, labelled in ((ax.xaxis, x_labelled), (ax.yaxis, True)):
        assert axis.get_offset_text().get_text() == ""
        labels = [t.get_text() for t in axis.get_ticklabels() if t.get_text()]
        assert bool(labels) == labelled
        assert not any("e" in t.lower() or "\N{MULTIPLICATION SIGN}" in t for t in labels), labels


@pytest.fixture(scope="module")
def ocp_study():
    # the brachistochrone's end height swept: the descent time and the final speed vary, x_f is fixed
    sweeps = [{"path": "states.1.final", "values": [5.0, 6.0, 7.0]}]
    spec, rows, (result, params) = _study("brachistochrone", {"transcription": {"intervals": 20}}, sweeps)
    return rows, chart(kind_spec=spec, title="t", sweeps=sweeps, rows=rows, result=result, params=params)


@pytest.fixture(scope="module")
def reentry_study():
    sweeps = [{"path": "path.max_heat_rate_w_m2", "values": [1.0e6, 9.0e5, 8.0e5]}]
    spec, rows, (result, params) = _study("betts-max-crossrange", {"grid": {"intervals": 20}}, sweeps)
    return rows, chart(kind_spec=spec, title="t", sweeps=sweeps, rows=rows, result=result, params=params)


def test_an_ocp_study_charts_the_objective_and_the_free_final_state_in_their_units(ocp_study):
    rows, c = ocp_study
    assert [r["status"] for r in rows] == ["succeeded"] * 3
    assert rows[0]["objective"] == pytest.approx(1.8016, abs=1e-3)    # the preset's published optimum
    # energy is conserved on a frictionless wire: v_f = sqrt(2 g (y0 - y_f)) (the re-flight's tolerance)
    for r in rows:
        assert r["final.v"] == pytest.approx(math.sqrt(2 * G0 * (10.0 - r["states.1.final"])), rel=1e-3)
    assert c.x_label == "final value of y [m]"
    assert [(p.key, p.label) for p in c.panels] == [("objective", "objective (minimize tf) [s]"),
                                                    ("final.v", "final v [m/s]")]
    assert c.constant == ["final.x"]                 # fixed by the problem: no flat line
    assert c.repeated == ["final.y"]                 # the swept value itself
    assert {"iterations", "limits_held", "verification_agrees", "sense"} <= set(c.table_only)
    assert [line.x for line in c.panels[0].lines] == [[5.0, 6.0, 7.0]]
    axes = _drawn(c)
    assert [ax.get_ylabel() for ax in axes] == ["objective (minimize tf) [s]", "final v [m/s]"]
    assert axes[-1].get_xlabel() == "final value of y [m]"
    for ax in axes:
        _no_offset(ax, x_labelled=ax is axes[-1])


def test_a_reentry_study_drops_fixed_terminal_values_and_labels_units(reentry_study):
    rows, c = reentry_study
    assert [r["status"] for r in rows] == ["succeeded"] * 3
    crossrange = [r["objective"] for r in rows]
    assert crossrange[0] > crossrange[1] > crossrange[2]            # a tighter limit costs crossrange
    for r in rows:   # the limit is active: the dense peak sits on it (the kind's 0.1 % limit tolerance)
        assert r["peak_heat_rate_w_m2"] == pytest.approx(r["path.max_heat_rate_w_m2"], rel=1e-3)
    assert c.x_label == "path.max_heat_rate [W/m^2]"
    labels = {p.key: p.label for p in c.panels}
    assert labels["objective"] == "crossrange (final latitude) [deg]"
    assert labels["tf_s"] == "flight time [s]"
    assert labels["peak_heat_rate_w_m2"] == "peak heating rate [W/m^2]"
    assert len(c.panels) <= 6 and list(labels)[:3] == ["objective", "tf_s", "peak_heat_rate_w_m2"]
    assert set(c.constant) == {"final.altitude_m", "final.speed_mps", "final.flight_path_deg"}
    assert "final.latitude_deg" in c.repeated            # the crossrange objective again
    assert not {"iterations", "limits_held", "terminal_held"} & set(labels)
    assert {"iterations", "limits_held", "terminal_held"} <= set(c.table_only)
    axes = _drawn(c)
    assert len(axes) == len(c.panels)
    assert axes[-1].get_xlabel() == "path.max_heat_rate [W/m^2]"
    for ax in axes:
        _no_offset(ax, x_labelled=ax is axes[-1])
    ticks = [t.get_text() for t in axes[-1].get_xticklabels() if t.get_text()]
    assert any(t.replace(",", "").startswith(("800000", "900000", "1000000")) for t in ticks), ticks


def test_robust_columns_say_monte_carlo_or_cadet_and_share_a_panel():
    outputs = KINDS["robust_reentry"].trade_outputs({"objective": {}}, None)
    sources = {o.key.split(".")[0] for o in outputs}
    assert {"mc", "cadet", "deterministic"} <= sources
    for o in outputs:
        if o.key.startswith("mc."):
            assert "Monte Carlo" in o.label
        if o.key.startswith("cadet."):
            assert "CADET" in o.label
    panels = {}
    for o in outputs:
        panels.setdefault(o.panel or o.key, set()).add(o.key.split(".")[0])
    assert {"mc", "cadet"} in panels.values()      # the promise beside its measurement


def test_names_carry_their_units():
    assert (name_label("path.max_heat_rate_w_m2"), name_unit("path.max_heat_rate_w_m2")) == \
        ("path.max_heat_rate", "W/m^2")
    assert (name_label("tf_bounds_s.1"), name_unit("tf_bounds_s.1")) == ("tf_bounds.1", "s")
    assert (name_label("seed"), name_unit("seed")) == ("seed", "")
    assert name_unit("terminal.speed_mps") == "m/s" and name_unit("a.b_deg") == "deg"
