"""Everything a robust ``ocp`` result has (issue 37 item 4), in process: the Monte Carlo's envelope against
the covariance known in closed form, the compiled propagation's traces against the numpy reference, the
plots' series against the stored numbers, and the CSV tables' rows."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from app.kinds import KINDS
from app.kinds.base import InProcessContext
from app.service.params import resolve_params
from tests.unit.test_ocp_robust import PUSHED, SB, SV


@pytest.fixture(scope="module")
def pushed_job():
    spec = KINDS["ocp"]
    resolved = resolve_params(spec, None, copy.deepcopy(PUSHED))
    out = spec.run(spec.params_model.model_validate(resolved), InProcessContext())
    assert out.status == "succeeded", out.error
    return out.result, resolved


def test_the_envelope_is_the_closed_form_spread_of_the_open_loop_plan(pushed_job):
    result, _ = pushed_job
    mc = result["robust"]["monte_carlo"]
    env = mc["envelope"]
    assert set(env["states"]) == {"x", "v", "y"} and set(env["constraints"]) == {"v_max"}
    t = np.asarray(env["t"])
    std = np.asarray(env["states"]["v"]["std"])
    exact = np.sqrt(SV ** 2 + (SB * t) ** 2)           # v = v0 + int(u) + w t, open loop
    n = result["robust"]["samples"]
    # the sample std's standard error is sigma / sqrt(2 n); 4 of them
    assert np.all(np.abs(std - exact) <= 4 * exact / np.sqrt(2 * n))
    # the named path constraint is v itself: the same numbers
    assert env["constraints"]["v_max"]["mean"] == env["states"]["v"]["mean"]
    # the mean flight is the design's mean (the dynamics are linear): the nodes, to the sampling error
    tr_v = np.interp(t, result["trajectory"]["t"], result["trajectory"]["v"])
    assert np.all(np.abs(np.asarray(env["states"]["v"]["mean"]) - tr_v) <= 4 * exact / np.sqrt(n) + 1e-9)
    assert len(mc["samples"]["objective"]) == n == 2000
    assert np.std(mc["samples"]["objective"]) == pytest.approx(result["robust"]["objective"]["std"], abs=1e-9)


def test_compiled_traces_are_the_numpy_reference():
    from solvers.ocp import parse_problem
    from solvers.ocp.robust.solver import solve_robust
    from solvers.uncertainty.montecarlo import run_monte_carlo

    body = copy.deepcopy(PUSHED)
    rs = solve_robust(parse_problem(body), params=body)
    compiled = run_monte_carlo(rs.monte_carlo_spec, 300, 5)
    reference = run_monte_carlo({**rs.monte_carlo_spec, "propagator": "numpy"}, 300, 5)
    assert set(compiled["envelope"]) == {"t_s", "state:x", "state:v", "state:y", "path:v_max"}
    for q, band in compiled["envelope"].items():
        if q != "t_s":
            for m in ("mean", "std"):
                assert np.allclose(band[m], reference["envelope"][q][m], rtol=0, atol=1e-12), q
    assert np.allclose(compiled["terminal_samples"]["objective"], reference["terminal_samples"]["objective"],
                       rtol=1e-12)


def test_the_plots_draw_the_stored_mean_and_k_sigma_band(pushed_job):
    from matplotlib.figure import Figure

    from app.results.plots import plots_for

    result, params = pushed_job
    by_name = {p.name: p for p in plots_for("ocp", result)}
    assert {"mc-state-x", "mc-state-v", "mc-state-y", "mc-constraint-v_max", "mc-objective"} <= set(by_name)
    rob = result["robust"]
    env = rob["monte_carlo"]["envelope"]
    for name, band, k, limit in (("mc-state-v", env["states"]["v"], rob["k"], None),
                                 ("mc-constraint-v_max", env["constraints"]["v_max"], rob["k_constraints"], 1.6)):
        fig = Figure()
        by_name[name].draw(fig, result, params)
        ax = fig.axes[0]
        lines = {ln.get_label(): ln for ln in ax.lines}
        assert np.allclose(lines["mean"].get_ydata(), band["mean"])
        verts = ax.collections[0].get_paths()[0].vertices[:, 1]
        mean, std = np.asarray(band["mean"]), np.asarray(band["std"])
        assert max(verts) == pytest.approx(max(mean + k * std), rel=1e-12)
        assert min(verts) == pytest.approx(min(mean - k * std), rel=1e-12)
        if limit is not None:
            assert lines["upper limit"].get_ydata()[0] == limit
    fig = Figure()
    by_name["mc-objective"].draw(fig, result, params)
    ax = fig.axes[0]
    assert sum(p.get_height() for p in ax.patches) == 2000
    marks = {ln.get_label(): ln.get_xdata()[0] for ln in ax.lines}
    assert marks["deterministic optimum"] == pytest.approx(12.0, rel=1e-3)
    assert marks["Monte Carlo mean"] == pytest.approx(rob["objective"]["mean"])
