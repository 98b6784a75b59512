"""Robust design of an ``ocp`` problem of several phases (issue 37 item 2): the covariance carried across the
links, against the closed form and against the same problem posed as one phase, and the Monte Carlo that
re-flies every phase.

The twin pair: x'' = u + w (w uncertain, v(0) and x(0) uncertain) moved rest to rest in 1 s, y' = -y + b
(b uncertain), minimising the integral of u^2 plus final(y) at mean + 2 sigma, with the speed limit v <= 1.6
held at mean + 2 sigma (active).  With piecewise-constant controls, 20 intervals in one phase and 10 + 10 in
two phases split at t = 0.5 are the same NLP (the controls are per interval, the nodes the same), so both
answers agree to IPOPT's tolerance (1e-8 scaled); the dynamics are linear and RK4 integrates their
polynomial parts exactly, so the propagated covariance of x and v is the closed form to round-off.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from solvers.ocp import PRESETS, parse_problem
from tests.support import robust_confirmed

DYN = {"x": "v", "v": "u + w", "y": "-y + b"}
UNCERTAINTY = {"parameters": {"w": {"distribution": "normal", "sigma": 0.2}, "b": {"distribution": "normal", "sigma": 0.2}},
               "initial": {"x": {"sigma": 0.1}, "v": {"sigma": 0.05}}}
ROBUST = {"k": 2.0, "constraints": ["v_max"], "monte_carlo": {"samples": 2000, "rounds": 2}}
SW, SB, SX, SV, K = 0.2, 0.2, 0.1, 0.05, 2.0
V_MAX = {"name": "v_max", "expr": "v", "upper": 1.6}
U = {"name": "u", "lower": -20.0, "upper": 20.0}


def _tr(n):
    return {"method": "multiple_shooting", "intervals": n, "control": "constant", "substeps": 2}


ONE = {"constants": {"b": 1.0, "w": 0.0},
       "states": [{"name": "x", "initial": 0.0, "final": 1.0, "scale": 1.0},
                  {"name": "v", "initial": 0.0, "final": 0.0, "scale": 1.0}, {"name": "y", "initial": 0.0, "scale": 1.0}],
       "controls": [U], "time": {"initial": 0.0, "final": 1.0}, "dynamics": DYN, "path": [V_MAX],
       "objective": {"sense": "minimize", "expr": "final(y)", "integrand": "u**2"},
       "transcription": _tr(20), "uncertainty": UNCERTAINTY, "robust": ROBUST}
TWO = {"constants": {"b": 1.0, "w": 0.0},
       "phases": [
           {"name": "a", "states": [{"name": "x", "initial": 0.0, "scale": 1.0}, {"name": "v", "initial": 0.0, "scale": 1.0},
                                    {"name": "y", "initial": 0.0, "scale": 1.0}],
            "controls": [U], "time": {"initial": 0.0, "final": 0.5}, "dynamics": DYN, "path": [V_MAX],
            "transcription": _tr(10)},
           {"name": "b", "states": [{"name": "x", "final": 1.0, "scale": 1.0}, {"name": "v", "final": 0.0, "scale": 1.0},
                                    {"name": "y", "scale": 1.0}],
            "controls": [U], "time": {"initial": 0.5, "final": 1.0}, "dynamics": DYN, "path": [V_MAX],
            "transcription": _tr(10)}],
       "objective": {"sense": "minimize", "expr": 'final(y, "b")', "integrand": "u**2"},
       "uncertainty": UNCERTAINTY, "robust": ROBUST}


@pytest.fixture(scope="module")
def twins():
    return robust_confirmed(ONE, 4), robust_confirmed(TWO, 4)


def test_the_covariance_crosses_the_link_as_the_closed_form(twins):
    _, (rs, block, _) = twins
    assert rs.solution.status.ok, rs.solution.status.message
    assert [p["name"] for p in rs.solution.phases] == ["a", "b"]
    for d in rs.design.phases:            # S = dx/dw, w = [xi_x, xi_v, dw, db]; P = S Sigma S^T
        t, n = d.t_nodes, 4                # x, v, y and the integral of u^2
        S = d.Z[n:].reshape(n, 4, -1, order="F")
        var_v = (S[1] ** 2 * np.array([1.0, 1.0, SW ** 2, SB ** 2])[:, None]).sum(axis=0)
        var_x = (S[0] ** 2 * np.array([1.0, 1.0, SW ** 2, SB ** 2])[:, None]).sum(axis=0)
        # exact: RK4 integrates polynomials of degree <= 4 exactly
        np.testing.assert_allclose(var_v, SV ** 2 + (SW * t) ** 2, rtol=1e-12)
        np.testing.assert_allclose(var_x, SX ** 2 + (SV * t) ** 2 + (SW * t ** 2 / 2) ** 2, rtol=1e-12)
        # y: the exponential within RK4's error, (h/2)^4 / 120 ~ 3e-9 at h = 0.05
        np.testing.assert_allclose(np.abs(S[2, 3]) * SB, SB * (1.0 - np.exp(-t)), atol=1e-8)
    a, b = rs.design.phases
    np.testing.assert_allclose(b.Z[4:, 0].reshape(4, 4, order="F")[:3], a.Z[4:, -1].reshape(4, 4, order="F")[:3],
                               atol=1e-12)
    assert block["objective"]["cadet_std"] == pytest.approx(SB * (1.0 - math.exp(-1.0)), abs=1e-8)


def test_two_phases_give_the_one_phase_twins_robust_design(twins):
    (one, b1, _), (two, b2, _) = twins
    # the same NLP: IPOPT's tolerance (1e-8 scaled) on an objective of about 13
    assert two.solution.objective == pytest.approx(one.solution.objective, rel=1e-7)
    assert two.deterministic.objective == pytest.approx(one.deterministic.objective, rel=1e-7)
    assert two.solution.objective > two.deterministic.objective + K * SB * (1 - math.exp(-1)) + 0.3   # the margin's price
    assert b2["objective"]["cadet_mean"] == pytest.approx(b1["objective"]["cadet_mean"], rel=1e-7)
    u1 = np.asarray(one.solution.trajectory["u"])
    u2 = np.concatenate([np.asarray(p["trajectory"]["u"]) for p in two.solution.phases])
    np.testing.assert_allclose(np.delete(u2, 10)[:-1], u1[:-1], atol=1e-5)     # phase b's first node is a's last
    # the limit is active in phase b (v peaks where its sigma has grown), at mean + k sigma, at the nodes
    tr = two.solution.phases[1]["trajectory"]
    t, v = np.asarray(tr["t"]), np.asarray(tr["v"])
    kc = b2["k_constraints"]
    assert np.max(v + kc * np.sqrt(SV ** 2 + (SW * t) ** 2)) == pytest.approx(1.6, abs=1e-6)


def test_the_monte_carlo_re_flies_every_phase_and_confirms(twins):
    (_, b1, s1), (_, b2, s2) = twins
    assert b2["confirmed"] is True and s2["failed_samples"] == 0 and s2["samples"] == 2000
    c = b2["constraints"]["v_max"]
    assert c["kept_fraction"] >= c["required_fraction"] - c["sampling_tolerance"]
    # the same draws flown through two phases and through one: the same flights (the designs agree to 1e-7)
    assert s2["terminal"]["objective"]["mean"] == pytest.approx(s1["terminal"]["objective"]["mean"], abs=1e-6)
    assert c["kept_fraction"] == pytest.approx(b1["constraints"]["v_max"]["kept_fraction"], abs=1.5 / 2000)
    # linear in the draws: the Monte Carlo's moments are CADET's within the sampling error (4 standard errors)
    sd = b2["objective"]["cadet_std"]
    assert b2["objective"]["mean"] == pytest.approx(b2["objective"]["cadet_mean"], abs=4 * sd / math.sqrt(2000))
    assert b2["objective"]["std"] == pytest.approx(sd, abs=4 * sd / math.sqrt(2 * 2000))


def test_a_link_of_states_in_a_robust_problem_carries_the_covariance():
    """Once refused (issue 37): the stage drop sets stage 2's mass (tests/unit/test_ocp_robust_links.py)."""
    from solvers.ocp.robust.links import carried_links

    body = copy.deepcopy(PRESETS["two-stage-ascent"]["params"])
    body["uncertainty"] = {"parameters": {"g": {"distribution": "normal", "sigma": 0.01}}}
    (link,) = carried_links(parse_problem(body))
    assert (link.index, link.after, link.target, link.value) == (0, 1, "m", 0.0)


def test_an_lgl_phase_of_a_robust_problem_succeeds_through_the_kind():
    """Once refused at its transcription (LGL was not done): now collocated (tests/unit/test_ocp_robust_lgl.py)."""
    from app.kinds.ocp.kind import run
    from app.kinds.ocp.params import OcpParams
    from tests.support import RecordingContext

    body = copy.deepcopy(TWO)
    body["phases"][1]["transcription"] = {"method": "lgl", "intervals": 5}
    body["robust"]["monte_carlo"] = {"samples": 400, "rounds": 0}
    out = run(OcpParams.model_validate(body), RecordingContext())
    assert out.status == "succeeded", out.error
    assert out.result["robust"]["confirmed"] is True


def test_a_robust_job_of_two_phases_succeeds_through_the_kind_with_its_phases_and_robust_block():
    from app.kinds.ocp.kind import run
    from app.kinds.ocp.params import OcpParams
    from app.kinds.ocp.result import OcpResult
    from tests.support import RecordingContext

    out = run(OcpParams.model_validate(copy.deepcopy(TWO)), RecordingContext())
    assert out.status == "succeeded", out.error
    assert [p["name"] for p in out.result["phases"]] == ["a", "b"]
    assert out.result["robust"]["confirmed"] is True
    assert out.result["robust"]["constraints"]["v_max"]["cadet"]["phase"] == "b"      # where it binds
    OcpResult.model_validate(out.result)


def test_the_monte_carlo_model_is_built_once_per_design_and_again_for_another():
    from solvers.ocp.robust.montecarlo import monte_carlo_model, monte_carlo_spec
    from solvers.ocp.robust.nlp import Design, PhaseDesign

    problem = parse_problem(copy.deepcopy(TWO))
    phases = [PhaseDesign(t0=t0, tf=t0 + 0.5, theta=np.zeros(0), Z=np.zeros((3, 1)), U=np.zeros((1, 10)),
                          t_nodes=np.linspace(t0, t0 + 0.5, 11)) for t0 in (0.0, 0.5)]
    spec = monte_carlo_spec(TWO, problem=problem, rob=problem.robust, design=Design(phases))
    assert monte_carlo_model(spec["model_params"]) is monte_carlo_model(copy.deepcopy(spec["model_params"]))
    phases[1].U = np.ones((1, 10))
    other = monte_carlo_spec(TWO, problem=problem, rob=problem.robust, design=Design(phases))
    assert monte_carlo_model(other["model_params"]) is not monte_carlo_model(spec["model_params"])
