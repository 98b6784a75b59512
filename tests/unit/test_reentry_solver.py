"""Betts shuttle benchmark by direct multiple shooting: golden numbers, status, verification."""
import numpy as np
import pytest

from solvers.common import Outcome
from solvers.models import shuttle as sh
from solvers.reentry import InitialGuess, ReentryProblem, solve
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
    from solvers.reentry import rhs_numpy
    ver = repropagate(rhs=rhs_numpy(sh.SHUTTLE), x0=sh.BETTS_INITIAL_STATE, t_nodes=s.t,
                      x_nodes=s.x, u_nodes=bad_u, control="linear")
    assert abs(ver.final_difference[2]) / DEG > 0.1


def test_warm_start_from_previous_arrays_converges_fast(crossrange):
    s = crossrange
    guess = InitialGuess(t=s.t, x=s.x, u=s.u_nodes_at_t)
    s2 = solve(ReentryProblem(intervals=50), initial_guess=guess)
    assert s2.status.outcome is Outcome.OPTIMAL
    assert s2.objective_value / DEG == pytest.approx(34.1412, abs=2e-3)
    assert s2.status.iterations <= 15


def test_heat_limited_100_intervals():
    s = solve(ReentryProblem(intervals=100, max_heat_rate_w_m2=sh.BETTS_HEAT_LIMIT_W_M2))
    assert s.status.outcome is Outcome.OPTIMAL and s.status.solver_status == "Solve_Succeeded"
    assert s.objective_value / DEG == pytest.approx(30.6255, abs=0.01)
    assert s.tf_s == pytest.approx(2198.67, abs=2.0)
    assert np.max(s.heat_rate) <= sh.BETTS_HEAT_LIMIT_W_M2 * (1 + 1e-6)
    # Between nodes the limit is overshot (spec: ~70.4 BTU/ft^2/s); reported, not hidden.
    q_dense = s.verification.path_max["heat_rate_w_m2"] / sh.BTU_FT2_S_TO_W_M2
    assert 70.0 < q_dense < 70.8
    assert any("exceeds" in n for n in s.notes)


@pytest.mark.slow
def test_heat_limited_400_intervals():
    s = solve(ReentryProblem(intervals=400, max_heat_rate_w_m2=sh.BETTS_HEAT_LIMIT_W_M2))
    assert s.status.outcome is Outcome.OPTIMAL
    assert s.objective_value / DEG == pytest.approx(30.6255, abs=0.005)
    assert s.tf_s == pytest.approx(2198.67, abs=0.5)
