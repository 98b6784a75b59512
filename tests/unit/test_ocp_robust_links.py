"""Robust design across links that set the next phase's start from the previous end (issue 37): a renamed and
a scaled state, against the same problem posed as one phase; the refusals of link forms that cannot carry the
covariance; a robust two-stage ascent whose dropped structure is uncertain, confirmed by its Monte Carlo.

The twin pair is ``tests/unit/test_ocp_robust_phases.py``'s (x'' = u + w, y' = -y + b, 20 intervals in one
phase or 10 + 10), with phase b's states renamed: ``X = x`` (an identity between different states) and
``V = 2 v`` (an affine map), its dynamics and speed limit rewritten in them, ``y`` continuous by default.  The
robust NLP is the same NLP in other units, so both answers agree to IPOPT's tolerance (1e-8 scaled): the
covariance J P J^T carried by the links is the one-phase propagation's (closed form in
test_ocp_robust_phases.py)."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from solvers.ocp import PRESETS, OcpInputError, parse_problem
from tests.support import robust_confirmed
from tests.unit.test_ocp_robust_phases import ONE, TWO, U

RENAMED = copy.deepcopy(TWO)
RENAMED["phases"][1].update({
    "states": [{"name": "X", "final": 1.0, "scale": 1.0}, {"name": "V", "final": 0.0, "scale": 2.0},
               {"name": "y", "scale": 1.0}],
    "dynamics": {"X": "V/2", "V": "2*(u + w)", "y": "-y + b"},
    "path": [{"name": "v_max", "expr": "V/2", "upper": 1.6}], "controls": [U]})
RENAMED["links"] = [{"name": "same_x", "expr": 'initial(X, "b") - final(x, "a")', "lower": 0.0, "upper": 0.0},
                    {"name": "speed_doubled", "expr": 'initial(V, "b") - 2*final(v, "a")', "lower": 0.0, "upper": 0.0}]


@pytest.fixture(scope="module")
def twins():
    return robust_confirmed(ONE, 4), robust_confirmed(RENAMED, 4)


def test_links_of_renamed_and_scaled_states_carry_the_one_phase_covariance(twins):
    (one, b1, s1), (two, b2, s2) = twins
    assert two.solution.status.ok, two.solution.status.message
    assert two.solution.objective == pytest.approx(one.solution.objective, rel=1e-7)
    assert b2["objective"]["cadet_std"] == pytest.approx(b1["objective"]["cadet_std"], rel=1e-7)
    assert b2["objective"]["cadet_mean"] == pytest.approx(b1["objective"]["cadet_mean"], rel=1e-7)
    # the start of phase b: S_b(t0) = J S_a(tf), J = d(X, V)/d(x, v) = diag(1, 2), on every column
    a, b = two.design.phases
    Sa = a.Z[4:, -1].reshape(4, 4, order="F")
    Sb = b.Z[4:, 0].reshape(4, 4, order="F")
    np.testing.assert_allclose(Sb[0], Sa[0], atol=1e-12)
    np.testing.assert_allclose(Sb[1], 2.0 * Sa[1], atol=1e-12)
    np.testing.assert_allclose(Sb[2], Sa[2], atol=1e-12)
    # the one-phase design's sigma of v at the split, doubled, is phase b's sigma of V at its start
    s1_nodes = one.design.Z[4:, 10].reshape(4, 4, order="F")
    w = np.array([1.0, 1.0, 0.2 ** 2, 0.2 ** 2])
    assert math.sqrt(np.sum(Sb[1] ** 2 * w)) == pytest.approx(2 * math.sqrt(np.sum(s1_nodes[1] ** 2 * w)), rel=1e-6)
    # the same draws through the links: the same flights as through one phase
    assert b2["confirmed"] is True and s2["failed_samples"] == 0
    assert s2["terminal"]["objective"]["mean"] == pytest.approx(s1["terminal"]["objective"]["mean"], abs=1e-6)
    assert b2["constraints"]["v_max"]["kept_fraction"] == pytest.approx(
        b1["constraints"]["v_max"]["kept_fraction"], abs=1.5 / 2000)


def test_an_expression_map_carries_the_covariance_by_its_jacobian_and_the_draws_by_newton(twins):
    """V**3 = 8 v**3 is V = 2 v for real numbers: h_y = 3 V**2, J = 24 v**2 / (3 V**2) = 2 at the design, and each
    draw's V solved by Newton; the design, CADET and the same draws' Monte Carlo are the affine link's."""
    _, (two, b2, s2) = twins
    body = copy.deepcopy(RENAMED)
    body["links"][1]["expr"] = 'initial(V, "b")**3 - 8*final(v, "a")**3'
    rs, block, summary = robust_confirmed(body, 4)
    assert rs.solution.objective == pytest.approx(two.solution.objective, rel=1e-9)
    assert block["objective"]["cadet_std"] == pytest.approx(b2["objective"]["cadet_std"], rel=1e-9)
    assert summary["failed_samples"] == 0
    assert summary["terminal"]["objective"]["mean"] == pytest.approx(s2["terminal"]["objective"]["mean"], rel=1e-9)


@pytest.mark.parametrize("link, says", [
    ({"expr": 'initial(X, "b") - final(x, "a")', "lower": -0.1, "upper": 0.1}, "inequality"),
    ({"expr": 'initial(X, "b") + initial(V, "b") - final(x, "a")', "lower": 0.0, "upper": 0.0}, "one equation"),
    ({"expr": 'final(X, "b") - final(x, "a")', "lower": 0.0, "upper": 0.0}, "final(X"),
    ({"expr": 'initial(y, "b") - final(x, "a")', "lower": 0.0, "upper": 0.0}, "default continuity"),
])
def test_a_link_that_cannot_carry_the_covariance_is_refused_naming_it(link, says):
    body = copy.deepcopy(RENAMED)
    body["links"] = [{"name": "odd", **link}, body["links"][1]]
    with pytest.raises(OcpInputError) as exc:
        parse_problem(body)
    assert exc.value.path == "params.links.0" and "odd" in exc.value.reason and says in exc.value.reason
    del body["uncertainty"], body["robust"]      # the deterministic problem takes each of them
    parse_problem(body)


TWO_STAGE_ROBUST = copy.deepcopy(PRESETS["two-stage-ascent"]["params"])
TWO_STAGE_ROBUST["uncertainty"] = {"parameters": {"dry1": {"distribution": "normal", "sigma": 5.0}}}
TWO_STAGE_ROBUST["robust"] = {"k": 2.0, "monte_carlo": {"samples": 2000, "rounds": 0}}


def test_a_robust_two_stage_ascent_with_an_uncertain_dropped_structure_is_confirmed_by_its_monte_carlo():
    rs, block, summary = robust_confirmed(TWO_STAGE_ROBUST, 7)
    assert rs.solution.status.ok, rs.solution.status.message
    assert block["confirmed"] is True and summary["failed_samples"] == 0
    obj = block["objective"]
    assert obj["cadet_std"] > 0
    # first order in a 5 kg sigma on a 300 kg stage (the second-order terms of ln(m) ~ 1e-4 of the apogee):
    # the Monte Carlo's moments are CADET's within 4 standard errors (measured: std 44165 m against 43167 m,
    # mean 1163838 m against 1164151 m)
    sd = obj["cadet_std"]
    assert obj["std"] == pytest.approx(sd, abs=4 * sd / math.sqrt(2 * 2000))
    assert obj["mean"] == pytest.approx(obj["cadet_mean"], abs=4 * sd / math.sqrt(2000))
    assert rs.solution.objective == pytest.approx(obj["cadet_mean"] - 2.0 * obj["cadet_std"], rel=1e-6)


def test_the_plots_of_several_phases_draw_every_phases_states_with_cadets_band():
    from matplotlib.figure import Figure

    from app.kinds import KINDS
    from app.kinds.base import InProcessContext
    from app.kinds.ocp.result import OcpResult
    from app.results.plots import plots_for
    from app.service.params import resolve_params

    spec = KINDS["ocp"]
    params = resolve_params(spec, None, copy.deepcopy(RENAMED))
    out = spec.run(spec.params_model.model_validate(params), InProcessContext())
    assert out.status == "succeeded", out.error
    result = out.result
    OcpResult.model_validate(result)
    rob = result["robust"]
    by_name = {p.name: p for p in plots_for("ocp", result)}
    assert {f"mc-state-{x}" for x in ("x", "v", "y", "X", "V")} | {"mc-constraint-v_max"} <= set(by_name)
    env, cadet = rob["monte_carlo"]["envelope"], rob["cadet_envelope"]
    ta, tb = (np.asarray(p["trajectory"]["t"]) for p in result["phases"])
    assert env["t"] == [*ta, *tb] and cadet["t"] == [*ta, *tb]        # one time axis: a's nodes, then b's
    k = rob["k"]
    for x, own in (("x", ta), ("X", tb), ("V", tb), ("y", np.concatenate([ta, tb]))):
        fig = Figure()
        by_name[f"mc-state-{x}"].draw(fig, result, params)
        ax = fig.axes[0]
        lines = {ln.get_gid() or ln.get_label(): ln for ln in ax.lines}
        mc = np.asarray(env["states"][x]["mean"], float)
        np.testing.assert_allclose(lines["mean"].get_ydata(), mc, equal_nan=True)
        assert np.isfinite(mc).sum() == own.size                        # the phase that has the state, only
        dots = np.concatenate([ln.get_xdata() for ln in ax.lines if ln.get_marker() == "."])   # one per phase
        np.testing.assert_allclose(dots, own)
        up, lo = (np.asarray(lines[g].get_ydata(), float) for g in ("cadet-upper", "cadet-lower"))
        std = np.array([np.nan if v is None else v for v in cadet["states"][x]["std"]])
        np.testing.assert_allclose((up - lo) / (2 * k), std, rtol=1e-12, equal_nan=True)
    # the speed limit (v in a, V/2 in b): CADET's sigma is the closed form sqrt(SV^2 + (SW t)^2) in both phases
    # (RK4 exact on the polynomial), drawn at mean +- k_c sigma beside the Monte Carlo's band
    fig = Figure()
    by_name["mc-constraint-v_max"].draw(fig, result, params)
    lines = {ln.get_gid(): ln for ln in fig.axes[0].lines if ln.get_gid()}
    t, kc = np.asarray(cadet["t"]), rob["k_constraints"]
    std = np.asarray(cadet["constraints"]["v_max"]["std"], float)
    np.testing.assert_allclose(std, np.sqrt(0.05 ** 2 + (0.2 * t) ** 2), rtol=1e-12)
    up, lo = (np.asarray(lines[g].get_ydata(), float) for g in ("cadet-upper", "cadet-lower"))
    np.testing.assert_allclose((up - lo) / (2 * kc), std, rtol=1e-12)
    # linear dynamics: at the end, the Monte Carlo's sigma of V is CADET's within 4 standard errors (2000 draws)
    sd = cadet["states"]["V"]["std"][-1]
    assert env["states"]["V"]["std"][-1] == pytest.approx(sd, abs=4 * sd / math.sqrt(2 * 2000))
    # the stored CADET sigma of V at b's start is twice v's at a's end (the link's J = 2)
    assert cadet["states"]["V"]["std"][ta.size] == pytest.approx(2 * cadet["states"]["v"]["std"][ta.size - 1],
                                                                 rel=1e-12)
