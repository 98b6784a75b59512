"""Robust reentry (paper 001): DO vs RO, Monte Carlo of both, CADET vs Monte Carlo.

Reference numbers: shared/specs/robust_reentry.md (careful reimplementation, 100 intervals):
tf DO 2199.26 s, RO 2225.71 s; heating limit kept over the flight (fine grid) DO 0.01%,
MC lat_f DO 29.909 / 0.554 deg, RO 28.913 / 0.253 deg.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from solvers import robust_reentry as rr
from solvers.common import Outcome
from solvers.models import reentry_dynamics as dyn
from solvers.models.reentry_state import STATE_NAMES
from solvers.uncertainty import montecarlo as mc

pytestmark = pytest.mark.slow
DEG = np.pi / 180


@pytest.fixture(scope="module")
def solved():
    problem = rr.RobustReentryProblem()
    problem.base.substeps = 2
    sol = rr.solve(problem)
    return problem, sol


@pytest.fixture(scope="module")
def monte_carlo(solved):
    problem, sol = solved
    out = {}
    for name, t, u in (("do", sol.deterministic.t, sol.deterministic.u_nodes_at_t), ("ro", sol.t, sol.u)):
        pred = rr.predict(problem, t=t, u=u, second_order=True)
        spec = rr.monte_carlo_spec(problem, t=t, u=u, cadet_sigma=pred.terminal_sigma, substeps=5)
        out[name] = (spec, pred, mc.run_monte_carlo(spec, 10000, 2020, chunk_size=2500))
    return out


def test_deterministic_and_robust_solves(solved):
    _, sol = solved
    assert sol.deterministic.status.outcome is Outcome.OPTIMAL
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    assert sol.status.solver_status == "Solve_Succeeded"
    assert [s["status"] for s in sol.stages if s["stage"].startswith("robust")] == ["Solve_Succeeded"] * 2
    assert sol.deterministic.tf_s == pytest.approx(2199.26, abs=0.5)
    # robust flight is longer; our RO optimum vs the reference reimplementation's 2225.71 s
    assert sol.tf_s > sol.deterministic.tf_s + 10.0
    assert sol.tf_s == pytest.approx(2225.71, abs=3.0)
    # terminal means are on the requirements (first-order CADET mean in the NLP)
    assert sol.x[0, -1] == pytest.approx(80000 * 0.3048, abs=1e-3)
    assert sol.x[3, -1] == pytest.approx(2500 * 0.3048, abs=1e-4)
    # robust objective mu - 3 sigma below the mean, sigma limits inactive
    pred = sol.robust_prediction
    assert sol.objective_value == pytest.approx(sol.x[2, -1] - 3 * pred.sigma[2, -1], abs=1e-9)
    assert pred.sigma[0, -1] < 4500 and pred.sigma[3, -1] < 250 and pred.sigma[4, -1] < 3 * DEG


def test_heating_limit_kept_over_whole_flight(monte_carlo):
    do, ro = monte_carlo["do"][2], monte_carlo["ro"][2]
    assert do["samples"] == ro["samples"] == 10000
    assert do["failed_samples"] == ro["failed_samples"] == 0
    assert ro["path"]["heat_rate"]["kept_fraction"] >= 0.99
    assert do["path"]["heat_rate"]["kept_fraction"] <= 0.01
    # nodes can only see less than the fine grid
    for s in (do, ro):
        assert s["path"]["heat_rate"]["kept_fraction_nodes"] >= s["path"]["heat_rate"]["kept_fraction"]


def test_robust_design_halves_latitude_spread_and_recentres_terminal_means(monte_carlo):
    do, ro = monte_carlo["do"][2]["terminal"], monte_carlo["ro"][2]["terminal"]
    assert do["latitude_rad"]["mean"] / DEG == pytest.approx(29.909, abs=0.05)
    assert do["latitude_rad"]["std"] / DEG == pytest.approx(0.554, rel=0.05)
    assert ro["latitude_rad"]["mean"] / DEG == pytest.approx(28.913, abs=0.05)
    assert ro["latitude_rad"]["std"] / DEG == pytest.approx(0.253, rel=0.05)
    assert ro["latitude_rad"]["std"] < 0.55 * do["latitude_rad"]["std"]
    req = {"altitude_m": 80000 * 0.3048, "speed_mps": 2500 * 0.3048}
    for q, v in req.items():
        # relative deviation of the MC mean from the requirement, as the paper reports it
        assert abs(ro[q]["mean"] - v) / v < 0.02
        assert abs(do[q]["mean"] - v) / v > 0.2
    within_do = monte_carlo["do"][2]["within"]
    within_ro = monte_carlo["ro"][2]["within"]
    for q in within_ro:
        assert within_ro[q]["sigma_limit"] > within_do[q]["sigma_limit"]


@pytest.mark.parametrize("design", ["do", "ro"])
def test_cadet_second_order_matches_monte_carlo(monte_carlo, design):
    _, pred, summary = monte_carlo[design]
    for i, q in enumerate(STATE_NAMES):
        st = summary["terminal"][q]
        sd = pred.sigma[i, -1]
        assert abs(st["mean"] - pred.mean[i, -1]) < 0.05 * sd, q
        # the final flight-path angle is the one quantity whose spread the linearization misses
        # (the terminal pull-up is strongly nonlinear): MC sigma 24% above CADET's for RO
        tol = 0.30 if q == "flight_path_rad" else 0.15
        assert st["std"] == pytest.approx(sd, rel=tol), q


def test_spec_is_json_and_split_equals_unsplit(monte_carlo):
    spec = monte_carlo["ro"][0]
    spec2 = json.loads(json.dumps(spec))
    one = mc.merge_chunks([mc.simulate_chunk(spec2, 99, 0, 800)])
    four = mc.merge_chunks([mc.simulate_chunk(spec2, 99, a, 200) for a in range(0, 800, 200)])
    assert one["path"] == four["path"] and one["within"] == four["within"]
    for q in one["terminal"]:
        assert four["terminal"][q]["mean"] == pytest.approx(one["terminal"][q]["mean"], rel=1e-12)
        assert four["terminal"][q]["std"] == pytest.approx(one["terminal"][q]["std"], rel=1e-9)


def test_step_doubling_changes_nothing_reported(monte_carlo):
    spec = dict(monte_carlo["ro"][0])
    a = mc.run_monte_carlo(spec, 1000, 5)
    b = mc.run_monte_carlo({**spec, "substeps": 10}, 1000, 5)
    assert a["path"]["heat_rate"]["kept_fraction"] == b["path"]["heat_rate"]["kept_fraction"]
    assert a["within"] == b["within"]
    for q in STATE_NAMES:
        assert abs(a["terminal"][q]["mean"] - b["terminal"][q]["mean"]) < 1e-3 * a["terminal"][q]["std"]


def test_monte_carlo_samples_against_solve_ivp(monte_carlo, solved):
    problem, sol = solved
    spec = monte_carlo["ro"][0]
    model = mc.resolve_model(spec["model"], spec["model_params"])
    x0, s = mc.draw_samples(spec, 2020, 17, 3, nx=6, ns=2)
    t = np.asarray(spec["t_nodes"])
    U = np.asarray(spec["controls"])
    xf = mc.propagate(model, x0=x0, s=s, t_nodes=t, controls=U, substeps=spec["substeps"])
    v = problem.base.vehicle
    for i in range(3):
        y = x0[:, i]
        for k in range(t.size - 1):
            def f(tt, yy, k=k, i=i):
                u = U[:, k] + (tt - t[k]) / (t[k + 1] - t[k]) * (U[:, k + 1] - U[:, k])
                return dyn.eom(yy, u, v, np, cd_scale=1 + s[0, i], cl_scale=1 + s[1, i])
            y = solve_ivp(f, (t[k], t[k + 1]), y, method="DOP853", rtol=1e-10, atol=1e-9).y[:, -1]
        assert abs(xf[0, i] - y[0]) < 1.0          # m
        assert abs(xf[3, i] - y[3]) < 0.01         # m/s
        # angles: RK4 with 4.4 s steps is within 1e-5 rad (6e-4 deg), 1/4000 of sigma(gamma_f)
        np.testing.assert_allclose(xf[[1, 2, 4, 5], i], y[[1, 2, 4, 5]], rtol=0, atol=1e-5)
