"""Betts shuttle benchmark by direct multiple shooting: golden numbers, status, verification."""
import numpy as np
import pytest

from solvers.common import Outcome
from solvers.models import shuttle as sh
from solvers.reentry import InitialGuess, ReentryProblem, path_quantities, rhs_numpy, solve
from solvers.verification import repropagate

DEG = sh.DEG


@pytest.fixture(scope="module")
def crossrange():
    return solve(ReentryProblem(intervals=100))


def test_betts_max_crossrange(crossrange):
    s = crossrange
    assert s.status.outcome is Outcome.OPTIMAL and s.status.solver_status == "Solve_Succeeded"
    assert s.objective_value / DEG == pytest.approx(34.1412, abs=1e-3)     # Betts 34.1412 deg
    assert s.tf_s == pytest.approx(2008.59, abs=0.5)                         # Betts 2008.59 s
    assert s.status.iterations < 60
    # Terminal equalities hold at the final node.
    assert s.x[0, -1] == pytest.approx(80000 * 0.3048, abs=1e-3)
    assert s.x[3, -1] == pytest.approx(2500 * 0.3048, abs=1e-4)
    assert s.x[4, -1] / DEG == pytest.approx(-5.0, abs=1e-6)


def test_verification_figures(crossrange):
    ver = crossrange.verification
    assert ver.ok
    assert abs(ver.final_difference[0]) < 30.48                            # 100 ft
    assert np.all(np.abs(ver.final_difference[[1, 2, 4, 5]]) / DEG < 0.01)
    assert np.max(ver.max_node_difference[[1, 2, 4, 5]]) / DEG < 0.01
    # The dense maximum can only be at least the node maximum.
    assert ver.path_max["heat_rate_w_m2"] >= crossrange.heat_rate.max() * (1 - 1e-9)


def test_two_rk4_substeps_track_the_adaptive_integrator(crossrange):
    """Why substeps=2: the discrete trajectory stays within 1 m of DOP853 at every node."""
    assert crossrange.verification.max_node_difference[0] < 1.0
    assert crossrange.verification.max_node_difference[3] < 0.05


def test_repropagation_detects_a_wrong_trajectory(crossrange):
    s = crossrange
    bad_u = s.u.copy()
    bad_u[1] += 5 * DEG                      # different bank profile
    ver = repropagate(rhs=rhs_numpy(sh.SHUTTLE), x0=sh.BETTS_INITIAL_STATE, t_nodes=s.t,
                      x_nodes=s.x, u_nodes=bad_u, control="linear")
    assert abs(ver.final_difference[2]) / DEG > 0.1


def test_warm_start_from_previous_arrays_converges_fast(crossrange):
    s = crossrange
    guess = InitialGuess(t=s.t, x=s.x, u=s.u_nodes_at_t)
    s2 = solve(ReentryProblem(intervals=50), initial_guess=guess)
    assert s2.status.outcome is Outcome.OPTIMAL
    assert s2.objective_value / DEG == pytest.approx(34.1412, abs=2e-3)
    assert s2.stages[0]["iterations"] <= 15     # the warm solve; a terminal round may follow (issue 25)


LIMIT = sh.BETTS_HEAT_LIMIT_W_M2


def heat_limited(m, **kw):
    return solve(ReentryProblem(intervals=m, max_heat_rate_w_m2=LIMIT, **kw))


def fine_grid_heat_max(s):
    """Worst heating rate on a fine grid (20 points per interval) by scipy's DOP853: a check
    independent of the solver's own RK4 re-propagation."""
    ver = repropagate(rhs=rhs_numpy(sh.SHUTTLE), x0=sh.BETTS_INITIAL_STATE, t_nodes=s.t, x_nodes=s.x,
                      u_nodes=s.u, control="linear", samples_per_interval=20,
                      path={"q": path_quantities(sh.SHUTTLE)["heat_rate_w_m2"]})
    assert ver.ok and ver.t.size == 20 * (s.t.size - 1) + 1
    return ver.path_max["q"]


@pytest.fixture(scope="module")
def heat_100():
    return heat_limited(100)


@pytest.mark.slow
def test_heat_limited_100_intervals(heat_100):
    s = heat_100
    assert s.status.outcome is Outcome.OPTIMAL and s.status.solver_status == "Solve_Succeeded"
    # Betts 30.6255 deg. The answer now keeps the limit between the nodes too (limits that hold:
    # enforced at every RK4 point, checked on the dense grid), which costs a little crossrange:
    # 30.6230 deg at 100 intervals where the node-only answer (which overshot by 0.61%) gave
    # 30.6279. 0.01 deg still separates it from any other local optimum.
    assert s.objective_value / DEG == pytest.approx(30.6255, abs=0.01)
    assert s.tf_s == pytest.approx(2198.67, abs=2.0)
    assert np.max(s.heat_rate) <= LIMIT * (1 + 1e-6)
    assert any("hold on the dense re-propagation" in n for n in s.notes)


@pytest.mark.parametrize("m", [50, 100, pytest.param(200, marks=pytest.mark.slow)])
@pytest.mark.slow
def test_default_heat_limited_answer_keeps_the_limit_between_nodes(m, heat_100):
    """Limits that hold: before, node enforcement overshot by 1.15% (50), 0.61% (100), 0.15% (200)."""
    s = heat_100 if m == 100 else heat_limited(m)
    assert s.status.outcome is Outcome.OPTIMAL, s.status.message
    q_fine = fine_grid_heat_max(s)
    assert q_fine <= LIMIT * 1.001
    lim = s.verification.limits["heat_rate_w_m2"]
    assert lim["held"] and lim["max"] <= LIMIT * 1.001 and lim["limit"] == LIMIT
    # The solver's own dense check and DOP853 agree on the worst value.
    assert lim["max"] == pytest.approx(q_fine, rel=1e-6)
    assert s.objective_value / DEG == pytest.approx(30.6255, abs=0.03)


def test_limit_that_cannot_be_made_to_hold_fails_with_its_code():
    """Node enforcement at 50 intervals overshoots by 1.15%; with no tightening round allowed
    the limit cannot hold: the solve says so (never a quiet success) and keeps the answer."""
    s = heat_limited(50, path_enforcement="nodes", limit_rounds=0)
    assert s.status.outcome is Outcome.LIMIT_NOT_HELD
    assert s.status.solver_status == "Solve_Succeeded"
    assert "heat_rate_w_m2" in s.status.message and "limit_rounds 0" in s.status.message
    lim = s.verification.limits["heat_rate_w_m2"]
    assert not lim["held"] and 0.005 < lim["excess"] < 0.03
    assert s.x.shape == (6, 51) and np.isfinite(s.objective_value)   # the diagnostic answer


@pytest.mark.slow
def test_tightening_rounds_make_node_enforcement_hold():
    s = heat_limited(50, path_enforcement="nodes")
    assert s.status.outcome is Outcome.OPTIMAL
    rounds = s.status.details["limit_rounds"]
    assert rounds[0]["excess"]["heat_rate_w_m2"] > 0.005 >= 0.001 >= rounds[-1]["excess"]["heat_rate_w_m2"]
    assert 2 <= len(rounds) <= 4 and s.stages[-1]["stage"].startswith("limit round")
    assert fine_grid_heat_max(s) <= LIMIT * 1.001


def test_dense_propagation_matches_dop853(crossrange):
    """The fast verification (fixed-step RK4 in one CasADi call) against scipy's DOP853."""
    s, ver = crossrange, crossrange.verification
    ref = repropagate(rhs=rhs_numpy(sh.SHUTTLE), x0=sh.BETTS_INITIAL_STATE, t_nodes=s.t, x_nodes=s.x,
                      u_nodes=s.u, control="linear", samples_per_interval=20)
    assert ver.t.size == ref.t.size == 2001 and np.allclose(ver.t, ref.t, rtol=0, atol=1e-9)
    assert np.max(np.abs(ver.x[0] - ref.x[0])) < 1e-3            # altitude, m
    assert np.max(np.abs(ver.x[3] - ref.x[3])) < 1e-4            # speed, m/s
    assert np.max(np.abs(ver.x[2] - ref.x[2])) < 1e-9            # latitude, rad
    # Its step-doubling error estimate is small and of the size of the true difference.
    assert ver.error_estimate[0] < 1e-3 and ver.error_estimate[0] > np.abs(ver.x[0, -1] - ref.x[0, -1]) / 100


@pytest.mark.slow
def test_heat_limited_400_intervals():
    s = solve(ReentryProblem(intervals=400, max_heat_rate_w_m2=sh.BETTS_HEAT_LIMIT_W_M2))
    assert s.status.outcome is Outcome.OPTIMAL
    assert s.objective_value / DEG == pytest.approx(30.6255, abs=0.005)
    assert s.tf_s == pytest.approx(2198.67, abs=0.5)


def test_simulated_guess_is_the_step_by_step_glide():
    """The guess's glide runs in one CasADi call; it is the numpy RK4 loop, to the bit."""
    from solvers.reentry import simulate_constant_controls
    pr = ReentryProblem()
    g = simulate_constant_controls(pr, alpha_rad=17 * DEG, bank_rad=-60 * DEG)
    rhs, u, x, xs = rhs_numpy(sh.SHUTTLE), np.array([17 * DEG, -60 * DEG]), np.array(sh.BETTS_INITIAL_STATE), []
    while x[0] > pr.terminal.altitude_m and x[3] > pr.terminal.speed_mps:
        k1 = rhs(x, u)
        k2 = rhs(x + 0.5 * 5.0 * k1, u)
        k3 = rhs(x + 0.5 * 5.0 * k2, u)
        k4 = rhs(x + 5.0 * k3, u)
        x = x + 5.0 / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        xs.append(x)
    assert g.x.shape == (6, len(xs) + 1) and np.array_equal(g.x[:, 1:], np.array(xs).T)
    assert np.array_equal(g.t, 5.0 * np.arange(len(xs) + 1))
