"""Finite-thrust interception (paper 003, method I): model, fuel, verification,
optimality diagnostics, warm start, cancellation."""
import numpy as np
import pytest

from solvers.astro.elements import Elements, elements_to_state
from solvers.astro.kepler import propagate
from solvers.common import Outcome
from solvers.intercept import InterceptProblem, ScanSettings, solve_impulsive
from solvers.intercept_thrust import (
    FiniteThrustProblem, ImpulsiveGuess, TrajectoryGuess, solve_finite_thrust,
)
from solvers.models import relative_motion as rm

MU = 3.986004418e14
D = np.radians
INTERCEPTOR = Elements(16678.137e3, 0.2, D(28.5), 0.0, 0.0, D(1.54))
TARGET = Elements(6878.137e3, 0.0, D(30.0), 0.0, 0.0, D(2.05))
REFERENCE_FUEL_KG = 270.84     # spec: careful reimplementation, 200-interval multiple shooting, g0 9.80665


def _problem(**kw):
    ri, vi = elements_to_state(MU, INTERCEPTOR)
    rt, vt = elements_to_state(MU, TARGET)
    return FiniteThrustProblem(r_interceptor_m=ri, v_interceptor_mps=vi, r_target_m=rt, v_target_mps=vt, **kw)


@pytest.fixture(scope="module")
def impulsive():
    sol = solve_impulsive(InterceptProblem(INTERCEPTOR, TARGET, scan=ScanSettings(step_s=5.0, retrograde=False)))
    assert sol.status.ok
    return ImpulsiveGuess(sol.best_t_man_s, sol.delta_v_vector_mps)


@pytest.fixture(scope="module")
def fixed_tf(impulsive):
    return solve_finite_thrust(_problem(), initial_guess=impulsive)


def test_hill_model_matches_inertial_two_body():
    """Unpowered nondimensional Hill dynamics reproduce two-body relative motion."""
    from scipy.integrate import solve_ivp
    ri, vi = elements_to_state(MU, INTERCEPTOR)
    rt, vt = elements_to_state(MU, TARGET)
    s = rm.HillScales.of(mu_m3_s2=MU, radius_m=float(np.linalg.norm(rt)), mass_kg=500.0)
    rho, rho_dot = rm.inertial_to_hill(r_i=ri, v_i=vi, r_t=rt, v_t=vt)
    x0 = np.r_[rho / s.length_m, rho_dot / s.speed_mps, 1.0]
    T = 3000.0
    sol = solve_ivp(lambda t, x: rm.dynamics_numpy(x[:, None], np.zeros((3, 1)), np.zeros(1))[:, 0],
                    (0, T / s.time_s), x0, method="DOP853", rtol=1e-12, atol=1e-13)
    ri2, vi2 = propagate(MU, ri, vi, T)
    rt2, vt2 = propagate(MU, rt, vt, T)
    rho2, rho_dot2 = rm.inertial_to_hill(r_i=ri2, v_i=vi2, r_t=rt2, v_t=vt2)
    np.testing.assert_allclose(sol.y[:3, -1] * s.length_m, rho2, atol=1.0)          # 1 m over 3000 s
    np.testing.assert_allclose(sol.y[3:6, -1] * s.speed_mps, rho_dot2, atol=1e-3)
    back_r, back_v = rm.hill_to_inertial(rho=rho, rho_dot=rho_dot, r_t=rt, v_t=vt)
    np.testing.assert_allclose(back_r, ri, atol=1e-6)
    np.testing.assert_allclose(back_v, vi, atol=1e-9)


def test_casadi_and_numpy_dynamics_agree():
    import casadi as ca
    rng = np.random.default_rng(3)
    x = np.r_[rng.normal(scale=0.3, size=6), 0.7]
    u = np.r_[0.6, rng.normal(size=3)]
    tmax, c = 0.47, 0.39
    f_ca = np.asarray(ca.Function("f", [], [rm.dynamics_casadi(ca.DM(x), ca.DM(u), tmax, c)])()["o0"]).ravel()
    f_np = rm.dynamics_numpy(x[:, None], (tmax * u[0] * u[1:])[:, None], np.array([tmax * u[0] / c]))[:, 0]
    np.testing.assert_allclose(f_ca, f_np, rtol=1e-13, atol=1e-14)


def test_fixed_tf_fuel_and_repropagated_miss(fixed_tf):
    """Numbers of the (feasible, possibly uncertified) fixed-tf solution."""
    sol = fixed_tf
    # feasible even when IPOPT does not certify optimality (it stalls: open problem)
    assert sol.status.outcome in (Outcome.OPTIMAL, Outcome.NOT_CONVERGED), sol.status.message
    assert sol.status.max_constraint_violation < 1e-6, sol.status.message
    assert abs(sol.fuel_kg - REFERENCE_FUEL_KG) <= 1.0, sol.fuel_kg
    assert sol.tf_s == pytest.approx(8080.5, abs=1e-6)
    v = sol.verification
    assert v["miss_distance_m"] < 100.0, v
    # the re-propagated propellant agrees with the collocation's to 0.01 kg
    assert abs(v["propellant_kg"] - sol.fuel_kg) < 0.01
    # burn structure: the main burn lies near the impulsive optimum (2870-3350 s)
    main = max(sol.burns, key=lambda b: b["duration_s"])
    assert 2800.0 < main["start_s"] < 3000.0 and 3250.0 < main["end_s"] < 3400.0, sol.burns
    assert np.max(np.linalg.norm(sol.thrust_n, axis=0)) <= 2000.0 * (1 + 1e-6)
    assert sol.states[6, 0] == pytest.approx(500.0)
    np.testing.assert_allclose(sol.states[:3, -1], 0.0, atol=1e-6)


def test_optimality_diagnostics_that_hold(fixed_tf):
    """Covector mapping: lambda_m(tf) = dJ/dm = -1, and thrust along -lambda_v in the burns.

    Not asserted (open problem, see the closing note of issue 5): IPOPT does not
    certify this solution (it stalls feasible to 1e-8), and the Hamiltonian varies
    by 26-46% of its term scale along the trajectory instead of staying constant.
    """
    o = fixed_tf.optimality
    assert o["costate_mass_final"] == pytest.approx(-1.0, abs=1e-3)
    assert o["thrust_primer_alignment_min_cos"] > 0.999


def test_warm_start_from_stored_trajectory_gives_same_answer(fixed_tf):
    sol = fixed_tf
    again = solve_finite_thrust(_problem(), initial_guess=TrajectoryGuess(sol.t_s, sol.states, sol.thrust_n))
    assert again.status.outcome is Outcome.OPTIMAL, again.status.message
    assert again.fuel_kg == pytest.approx(sol.fuel_kg, abs=0.05)
    assert again.verification["miss_distance_m"] < 100.0


def test_cancellation_returns_cancelled(impulsive):
    calls = []

    def stop():
        calls.append(1)
        return len(calls) > 3

    sol = solve_finite_thrust(_problem(), initial_guess=impulsive, should_stop=stop)
    assert sol.status.outcome is Outcome.CANCELLED
    assert sol.status.solver_status == "User_Requested_Stop"
    assert sol.status.iterations <= 5
