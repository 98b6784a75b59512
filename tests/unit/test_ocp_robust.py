"""Robust design of an ``ocp`` problem (issue 37; ``shared/specs/ocp.md``, "Robust design"): the uncertainty
checked at the door, CADET through the user's dynamics against the covariance known in closed form, the
Monte Carlo's draws, and the robust NLP's answer against its own Monte Carlo."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from pydantic import ValidationError

from app.kinds.ocp.params import OcpParams
from solvers.ocp import PRESETS, OcpInputError, parse_problem, solve
from solvers.ocp.robust.model import RobustSpec

# x'' = u moved from rest at 0 to rest at 1 in 1 s with least effort; y' = -y + b filters an uncertain constant.
# Linear: the first-order covariance is the exact one, P(t) = Phi P0 Phi^T plus the response to b.
LINEAR = {
    "constants": {"b": 1.0},
    "states": [{"name": "x", "initial": 0.0, "final": 1.0, "scale": 1.0},
               {"name": "v", "initial": 0.0, "final": 0.0, "scale": 1.0},
               {"name": "y", "initial": 0.0, "scale": 1.0}],
    "controls": [{"name": "u", "lower": -20.0, "upper": 20.0}],
    "time": {"initial": 0.0, "final": 1.0},
    "dynamics": {"x": "v", "v": "u", "y": "-y + b"},
    "path": [{"name": "y_max", "expr": "y", "upper": 2.0}],
    "objective": {"sense": "minimize", "integrand": "u**2"},
    "transcription": {"method": "multiple_shooting", "intervals": 20, "control": "linear", "substeps": 2},
    "uncertainty": {"parameters": {"b": {"distribution": "normal", "sigma": 0.2}},
                    "initial": {"x": {"sigma": 0.1}, "v": {"sigma": 0.05}}},
    "robust": {"k": 2.0, "constraints": ["y_max"], "monte_carlo": {"samples": 400}},
}
SX, SV, SB = 0.1, 0.05, 0.2


def _refused(params, path: str, words: str):
    with pytest.raises(OcpInputError) as exc:
        parse_problem(params)
    assert exc.value.path == path, exc.value
    assert words in exc.value.reason, exc.value.reason


def _with(**changes):
    p = copy.deepcopy(LINEAR)
    for k, v in changes.items():
        p[k] = v
    return p


# --- 1. the uncertainty as data, checked at the door ---------------------------------------------------------
def test_the_parsed_uncertainty_defaults_mean_to_the_declared_value_and_k_and_statistic():
    rob = parse_problem(LINEAR).robust
    assert isinstance(rob, RobustSpec)
    assert rob.parameters[0].mean == 1.0 and rob.parameters[0].sigma == 0.2
    assert [s.state for s in rob.initial] == ["x", "v"]
    assert rob.k == 2.0 and rob.objective == "mean_plus_k_sigma" and rob.samples == 400
    maxi = _with(objective={"sense": "maximize", "expr": "final(y)"}, robust={})
    assert parse_problem(maxi).robust.objective == "mean_minus_k_sigma" and parse_problem(maxi).robust.k == 3.0
    uni = _with(uncertainty={"parameters": {"b": {"distribution": "uniform", "lower": 0.5, "upper": 2.0}}})
    u = parse_problem(uni).robust.parameters[0]
    assert u.mean == 1.25 and u.sigma == pytest.approx(1.5 / math.sqrt(12.0))
    assert parse_problem(copy.deepcopy(PRESETS["brachistochrone"]["params"])).robust is None


@pytest.mark.parametrize("change,path,words", [
    ({"uncertainty": {"parameters": {"bb": {"distribution": "normal", "sigma": 0.1}}}},
     "params.uncertainty.parameters.bb", "did you mean 'b'"),
    ({"uncertainty": {"parameters": {"b": {"distribution": "normal", "sigma": -0.1}}}},
     "params.uncertainty.parameters.b.sigma", "positive"),
    ({"uncertainty": {"parameters": {"b": {"distribution": "uniform", "lower": 2.0, "upper": 1.0}}}},
     "params.uncertainty.parameters.b", "below"),
    ({"uncertainty": {"parameters": {"b": {"distribution": "lognormal", "sigma": 1.0}}}},
     "params.uncertainty.parameters.b.distribution", "neither"),
    ({"constants": {"b": 1.0, "unused": 2.0},
      "uncertainty": {"parameters": {"unused": {"distribution": "normal", "sigma": 0.1}}}},
     "params.uncertainty.parameters.unused", "no expression uses"),
    ({"uncertainty": {"initial": {"w": {"sigma": 1.0}}}}, "params.uncertainty.initial.w", "not a declared state"),
    ({"uncertainty": {"initial": {"x": {"sigma": 0.0}}}}, "params.uncertainty.initial.x.sigma", "positive"),
    ({"robust": {"constraints": ["y_mx"]}}, "params.robust.constraints.0", "did you mean 'y_max'"),
    ({"robust": {"k": -1}}, "params.robust.k", "outside"),
    ({"robust": {"monte_carlo": {"samples": 10 ** 7}}}, "params.robust.monte_carlo.samples",
     "max_monte_carlo_samples"),
    ({"uncertainty": None}, "params.uncertainty", "needs the uncertainty"),
])
def test_a_malformed_uncertainty_is_refused_naming_the_field(change, path, words):
    _refused(_with(**change), path, words)


def test_the_service_model_refuses_at_the_field_with_the_setting():
    bad = _with(robust={"monte_carlo": {"samples": 10 ** 7}})
    with pytest.raises(ValidationError) as exc:
        OcpParams.model_validate(bad)
    err = exc.value.errors()[0]
    assert err["loc"] == ("robust", "monte_carlo", "samples")
    assert "TRAJLAB_OCP_MAX_MONTE_CARLO_SAMPLES" in err["msg"]
    assert OcpParams.model_validate(copy.deepcopy(LINEAR)).problem.robust.k == 2.0


def test_robust_design_across_a_jump_that_sets_no_draws_start_is_refused_naming_it():
    body = copy.deepcopy(PRESETS["two-stage-ascent"]["params"])      # its stage drop links m across phases
    body["uncertainty"] = {"parameters": {"g": {"distribution": "normal", "sigma": 0.01}}}
    body["links"][0]["lower"] = -10.0       # a range bounds the plan; the equality carries (test_ocp_robust_links)
    _refused(body, "params.links.0", "stage1_drop")


# --- 2. CADET through the user's dynamics: the closed form ---------------------------------------------------
@pytest.fixture(scope="module")
def linear_design():
    from solvers.ocp.robust.nlp import RobustNLP

    problem = parse_problem(LINEAR)
    det = solve(problem)
    assert det.status.ok
    return problem, det, RobustNLP(problem, problem.robust)


def test_the_propagated_covariance_is_the_closed_form_of_the_linear_system(linear_design):
    problem, det, R = linear_design
    tr = det.trajectory
    t, U = np.asarray(tr["t"]), np.vstack([tr["u"]])
    Z = R.propagate(tf=det.tf, theta=np.zeros(0), X0=np.zeros(3), U=U)
    n = R.rf.n                                  # x, v, y and the integral of u^2
    m, Pxx, Pxs = R.rf.cad.covariance(Z, R.rf.theta_numbers(R.c, R.sigma_s))
    # RK4 is exact on the double integrator (polynomial) and within (h/2)^4/120 ~ 3e-9 of exp(-t) here
    np.testing.assert_allclose(m[2], 1.0 - np.exp(-t), atol=1e-8)
    np.testing.assert_allclose(Pxx[0, 0], SX ** 2 + t ** 2 * SV ** 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(Pxx[0, 1], t * SV ** 2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(Pxx[1, 1], SV ** 2, rtol=1e-12)
    np.testing.assert_allclose(Pxx[2, 2], SB ** 2 * (1.0 - np.exp(-t)) ** 2, rtol=1e-7, atol=1e-15)
    np.testing.assert_allclose(Pxx[0, 2], 0.0, atol=1e-15)
    np.testing.assert_allclose(Pxs[2, 0], SB ** 2 * (1.0 - np.exp(-t)), rtol=1e-7, atol=1e-15)
    assert n == 4 and np.allclose(Pxx[3, 3], 0.0)      # the control is open loop: the cost is certain


# v' = u + w with an uncertain push w: the speed limit v <= 1.6 at mean + 2 sigma is active (the deterministic
# rest-to-rest move peaks at v = 1.5 with sigma_v(t) = sqrt(0.05^2 + (0.2 t)^2)), so robustness costs effort.
PUSHED = _with(constants={"b": 1.0, "w": 0.0}, dynamics={"x": "v", "v": "u + w", "y": "-y + b"},
               path=[{"name": "v_max", "expr": "v", "upper": 1.6}],
               uncertainty={"parameters": {"w": {"distribution": "normal", "sigma": 0.2}},
                            "initial": {"v": {"sigma": 0.05}}},
               robust={"k": 2.0, "constraints": ["v_max"], "monte_carlo": {"samples": 2000, "rounds": 2}})


@pytest.fixture(scope="module")
def pushed():
    from solvers.ocp.robust.solver import design_and_confirm
    from solvers.uncertainty.montecarlo import run_monte_carlo

    problem = parse_problem(PUSHED)
    return design_and_confirm(problem, params=PUSHED, run_monte_carlo=run_monte_carlo, seed=3)


def test_the_robust_design_holds_its_limit_at_mean_plus_k_sigma_and_pays_for_it(pushed):
    rs, block, _ = pushed
    assert rs.solution.status.ok and block is not None
    assert rs.deterministic.objective == pytest.approx(12.0, rel=1e-3)      # integral of u^2, rest to rest
    assert rs.solution.objective > 12.2                                      # the price of the margin (12.35)
    tr = rs.solution.trajectory
    t, v = np.asarray(tr["t"]), np.asarray(tr["v"])
    sigma = np.sqrt(0.05 ** 2 + (0.2 * t) ** 2)                              # closed form, the control is open loop
    k_c = block["k_constraints"]
    assert np.max(v + k_c * sigma) == pytest.approx(1.6, abs=1e-6)          # active, at the nodes
    assert block["constraints"]["v_max"]["cadet"]["excess_scaled_dense"] <= 1e-3     # and between them
    assert block["objective"]["cadet_std"] == pytest.approx(0.0, abs=1e-9)  # the cost of an open-loop plan is certain
    assert block["objective"]["std"] == pytest.approx(0.0, abs=1e-9)


def test_the_monte_carlo_confirms_it_or_the_rounds_raise_k_until_it_does(pushed):
    _, block, summary = pushed
    c = block["constraints"]["v_max"]
    assert c["required_fraction"] == pytest.approx(0.97725, abs=1e-5)        # Phi(2)
    assert block["confirmed"] is True and c["kept"] is True
    assert c["kept_fraction"] >= c["required_fraction"] - c["sampling_tolerance"]
    first = block["rounds"][0]
    if len(block["rounds"]) > 1:        # a per-instant bound promises more than a whole flight keeps
        assert first["kept_fractions"]["v_max"] < c["required_fraction"] and block["k_constraints"] > 2.0
    assert summary["samples"] == 2000 and summary["failed_samples"] == 0


def test_doubled_sigmas_are_not_robust():
    from solvers.ocp.robust.solver import design_and_confirm
    from solvers.uncertainty.montecarlo import run_monte_carlo

    body = copy.deepcopy(PUSHED)
    body["robust"]["monte_carlo"].update(sigma_factor=2.0, rounds=0)
    rs, block, _ = design_and_confirm(parse_problem(body), params=body, run_monte_carlo=run_monte_carlo, seed=3)
    assert rs.solution.status.ok
    assert block["confirmed"] is False and block["sigma_factor"] == 2.0
    c = block["constraints"]["v_max"]
    assert c["kept_fraction"] < c["required_fraction"] - c["sampling_tolerance"]


# --- 3. the Monte Carlo's draws ------------------------------------------------------------------------------
def test_uniform_draws_stay_in_their_interval_and_chunks_do_not_change_the_answer():
    from solvers.uncertainty.montecarlo import draw_samples, run_monte_carlo

    spec = {"x0_mean": [0.0], "x0_cov": None, "s_mean": [1.25, 0.0], "s_cov": [[0.1875, 0.0], [0.0, 4.0]],
            "s_uniform": [[0.5, 2.0], None]}
    _, s = draw_samples(spec, 7, 0, 20000, nx=1, ns=2)
    assert s[0].min() >= 0.5 and s[0].max() <= 2.0
    assert s[0].mean() == pytest.approx(1.25, abs=0.01) and s[0].std() == pytest.approx(1.5 / math.sqrt(12), rel=0.02)
    assert s[1].std() == pytest.approx(2.0, rel=0.02)
    problem = parse_problem(LINEAR)
    from solvers.ocp.robust.montecarlo import monte_carlo_spec

    t = np.linspace(0.0, 1.0, 21)
    mc = monte_carlo_spec(LINEAR, problem=problem, rob=problem.robust, t_nodes=t, U=np.zeros((1, 21)),
                          x0=np.zeros(3), tf=1.0, theta=np.zeros(0))
    one, split = run_monte_carlo(mc, 600, 5), run_monte_carlo(mc, 600, 5, chunk_size=250)
    assert one["terminal"]["objective"] == split["terminal"]["objective"]
    assert one["path"]["y_max"]["kept_fraction"] == split["path"]["y_max"]["kept_fraction"]
