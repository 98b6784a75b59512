"""Finite-thrust interception (paper 003, method I): model, fuel, verification,
optimality diagnostics, warm start, cancellation."""
import numpy as np
import pytest

from dataclasses import replace

from solvers.astro.kepler import propagate
from solvers.common import Outcome, SolveStatus
from solvers.intercept import InterceptProblem, ScanSettings, solve_impulsive
from solvers.intercept.cases import CONVERGED_FUEL_KG, PAPER_003, REFERENCE_FUEL_KG
from solvers.intercept.thrust import (FiniteThrustProblem, ImpulsiveGuess, MeshOptions, TrajectoryGuess,
                                      solve_finite_thrust)
from solvers.models import relative_motion as rm

MU = PAPER_003.mu_m3_s2
# CONVERGED_FUEL_KG: benchmarks/intercept.py's multiple-shooting baseline gives 271.45-271.50 kg;
# the spec's REFERENCE_FUEL_KG (270.84) is about 0.6 kg low; the target is 1 kg around it.


def _problem(*, mesh=None, **scenario):
    sn = replace(PAPER_003, **scenario)
    return FiniteThrustProblem(scenario=sn) if mesh is None else FiniteThrustProblem(scenario=sn, mesh=mesh)


@pytest.fixture(scope="module")
def impulsive():
    sol = solve_impulsive(InterceptProblem(PAPER_003, scan=ScanSettings(step_s=5.0, retrograde=False)))
    assert sol.status.ok
    return ImpulsiveGuess(sol.best_t_man_s, sol.delta_v_vector_mps)


@pytest.fixture(scope="module")
def fixed_tf(impulsive):
    return solve_finite_thrust(_problem(), initial_guess=impulsive)


def test_hill_model_matches_inertial_two_body():
    """Unpowered nondimensional Hill dynamics reproduce two-body relative motion."""
    from scipy.integrate import solve_ivp
    ri, vi, rt, vt = PAPER_003.initial_states()
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


@pytest.mark.slow
def test_fixed_tf_fuel_and_repropagated_miss(fixed_tf):
    sol = fixed_tf
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    assert sol.status.max_constraint_violation < 1e-6, sol.status.message
    assert abs(sol.fuel_kg - REFERENCE_FUEL_KG) <= 1.0, sol.fuel_kg           # the target
    assert sol.fuel_kg == pytest.approx(CONVERGED_FUEL_KG, abs=0.01)
    assert sol.tf_s == pytest.approx(8080.5, abs=1e-6)
    v = sol.verification
    assert v["miss_distance_m"] < 10.0, v                                     # target: 100 m
    assert abs(v["propellant_kg"] - sol.fuel_kg) < 0.001
    # switching structure: a short burn at t=0 (found by the switching function, not guessed)
    # and the main burn around the impulsive optimum (spec: 2870-3270 s)
    assert [b["kind"] for b in sol.burns] == ["burn", "burn"], sol.burns
    first, main = sol.burns
    assert first["start_s"] < 1e-3 and 9.0 < first["duration_s"] < 10.5, first
    assert 2865.0 < main["start_s"] < 2880.0 and 3255.0 < main["end_s"] < 3270.0, main
    assert np.max(np.linalg.norm(sol.thrust_n, axis=0)) <= 2000.0 * (1 + 1e-6)
    assert sol.states[6, 0] == pytest.approx(500.0)
    np.testing.assert_allclose(sol.states[:3, -1], 0.0, atol=1e-6)
    assert sol.status.iterations < 100


def test_optimality_conditions_hold(fixed_tf):
    """Pontryagin, from the collocation multipliers (covector mapping, integral form):
    the Hamiltonian is constant and equals -dJ/dtf, lambda_m(tf) = dJ/dm_f = -1, the switching
    function is positive exactly on the burns, and the thrust points along -lambda_v."""
    o = fixed_tf.optimality
    assert o["hamiltonian_relative_variation"] < 1e-5, o       # (max - min) / term scale
    assert o["hamiltonian_relative_error"] < 1e-6, o           # mean vs -dJ/dtf from the tf multiplier
    assert o["costate_mass_final"] == pytest.approx(-1.0, abs=1e-6)
    assert o["switching_function_agreement"] == 1.0 and o["nodes_checked"] > 50, o
    assert o["switching_function_max_on_coasts"] < 0.0, o
    assert o["thrust_primer_alignment_min_cos"] > 1.0 - 1e-9


@pytest.mark.slow
def test_mesh_independence(impulsive, fixed_tf):
    """Sixteen nodes per segment and half the segment lengths: the same answer."""
    fine = solve_finite_thrust(_problem(mesh=MeshOptions(nodes=16, coast_segment_s=500.0, burn_segment_s=100.0)),
                               initial_guess=impulsive)
    assert fine.status.outcome is Outcome.OPTIMAL, fine.status.message
    assert fine.fuel_kg == pytest.approx(fixed_tf.fuel_kg, abs=1e-3)
    assert fine.burns[-1]["start_s"] == pytest.approx(fixed_tf.burns[-1]["start_s"], abs=0.01)


def test_warm_start_from_stored_trajectory_gives_same_answer(fixed_tf):
    sol = fixed_tf
    again = solve_finite_thrust(_problem(), initial_guess=TrajectoryGuess(sol.t_s, sol.states, sol.thrust_n))
    assert again.status.outcome is Outcome.OPTIMAL, again.status.message
    assert again.fuel_kg == pytest.approx(sol.fuel_kg, abs=0.001)
    assert again.verification["miss_distance_m"] < 10.0
    assert len(again.history) == 1                      # the burn structure came with the guess
    assert again.history[0]["iterations"] < sol.history[0]["iterations"] + sol.history[-1]["iterations"]


def test_cancellation_returns_cancelled(impulsive):
    calls = []

    def stop():
        calls.append(1)
        return len(calls) > 3

    sol = solve_finite_thrust(_problem(), initial_guess=impulsive, should_stop=stop)
    assert sol.status.outcome is Outcome.CANCELLED
    assert sol.status.solver_status == "User_Requested_Stop"
    assert sol.status.iterations <= 5


@pytest.mark.slow
def test_cancellation_in_a_later_round_is_still_cancelled(impulsive):
    """Cancelled while the second mesh is solving: the answer is the first mesh's, the status
    says cancelled (not optimal)."""
    first = solve_finite_thrust(_problem(mesh=MeshOptions(refine=False)), initial_guess=impulsive)
    n_first = first.status.iterations
    calls = []

    def stop():
        calls.append(1)
        return len(calls) > n_first + 3

    sol = solve_finite_thrust(_problem(), initial_guess=impulsive, should_stop=stop)
    assert sol.status.outcome is Outcome.CANCELLED, sol.status
    assert len(sol.history) == 2 and sol.fuel_kg == pytest.approx(first.fuel_kg, abs=1e-6)


@pytest.mark.slow
def test_paper_single_segment_60_nodes_misses_when_reflown(impulsive):
    """The paper's transcription (one 60-node LGL segment, free throttle): IPOPT converges
    near the right fuel, but a polynomial cannot hold the burn's jumps, and re-flying the
    controls misses by kilometres (spec pitfall); the result says so instead of 'optimal'."""
    mesh = MeshOptions(structure="free_throttle", segments=1, nodes=60, refine=False, max_iterations=3000)
    sol = solve_finite_thrust(_problem(mesh=mesh), initial_guess=impulsive)
    assert abs(sol.fuel_kg - CONVERGED_FUEL_KG) < 1.0
    assert sol.verification["miss_distance_m"] > 1000.0
    assert sol.status.outcome is Outcome.NOT_CONVERGED and "re-propagated miss" in sol.status.message


@pytest.mark.slow
def test_infeasible_propellant_is_reported_clearly(impulsive):
    sol = solve_finite_thrust(_problem(propellant_kg=150.0), initial_guess=impulsive)
    assert sol.status.outcome is Outcome.INFEASIBLE
    assert "150 kg of propellant" in sol.status.message


def _free(upper):
    from solvers.intercept import InterceptProblem, solve_finite
    return solve_finite(InterceptProblem(replace(PAPER_003, free_final_time=True, tf_bounds_s=(2000.0, upper))))


def test_free_final_time_within_2000_12000():
    """Free tf in [2000, 12000] s: an interior optimum (H = 0, tf off its bounds) at about
    10091 s with 174.78 kg, started from the best single impulse of the porkchop over the bounds."""
    sol = _free(12000.0)
    assert sol.status.outcome is Outcome.OPTIMAL, sol.status.message
    assert 10000.0 < sol.tf_s < 10200.0, sol.tf_s
    assert sol.fuel_kg == pytest.approx(174.78, abs=0.05)
    assert sol.verification["miss_distance_m"] < 10.0
    o = sol.optimality
    assert o["tf_free_and_off_bounds"] and abs(o["hamiltonian_expected"]) < 1e-9
    assert abs(o["hamiltonian_mean"]) / o["hamiltonian_scale"] < 1e-6, o
    assert o["hamiltonian_relative_variation"] < 1e-5, o


@pytest.mark.slow
def test_free_final_time_fuel_falls_with_the_upper_bound():
    """A larger upper bound admits every earlier answer, so the best fuel can only fall;
    it does, until the interior optimum near 10091 s is inside the bounds."""
    fuel = []
    for upper in (8080.5, 10000.0, 12000.0):
        sol = _free(upper)
        assert sol.status.outcome is Outcome.OPTIMAL, (upper, sol.status.message)
        # IPOPT relaxes bounds by 1e-8 (relative); the stated arrival never leaves them (issue 25)
        assert 2000.0 <= sol.tf_s <= upper and sol.t_s[-1] <= upper
        o = sol.optimality
        # at an active upper bound H = -dJ/dtf < 0 (more time would save fuel), else 0
        assert o["hamiltonian_relative_error"] < 1e-6, (upper, o)
        fuel.append(sol.fuel_kg)
    assert fuel[0] > fuel[1] > fuel[2], fuel
    assert fuel[0] <= CONVERGED_FUEL_KG + 0.01      # no worse than fixed tf = 8080.5 s


def test_preset_answer_has_no_zero_length_arcs():
    # The NLP drove the first coast of the paper case to its bound 0 (an 8-nanosecond arc holding a
    # whole segment of nodes, issue 15); such arcs are removed and the problem solved again.
    from tests.preset_results import solve_preset

    _, _, out = solve_preset("long-range-intercept")
    ft = out.result["finite_thrust"]
    assert ft["status"] == "optimal"
    assert all(a["duration_s"] > 1e-3 for a in ft["arcs"]), [a["duration_s"] for a in ft["arcs"]]
    assert [a["kind"] for a in ft["arcs"]] == ["burn", "coast", "burn", "coast"]
    assert ft["arcs"][0]["start_s"] == 0.0 and ft["arcs"][0]["duration_s"] == pytest.approx(9.7, abs=0.1)
    assert any(h.get("next", "").startswith("arcs shorter than") for h in ft["history"])
    # the answer is unchanged by the removal: same fuel, still verified
    assert ft["fuel_kg"] == pytest.approx(CONVERGED_FUEL_KG, abs=0.01)
    assert ft["verification"]["miss_distance_m"] < 100.0
    boundaries = ft["mesh"]["boundaries_s"]
    assert min(np.diff(boundaries)) > 1.0


def test_without_short_arcs_merges_and_keeps_the_total():
    from solvers.intercept.thrust.layout import Arc, Layout, without_short_arcs

    lay = Layout((Arc("coast", 1), Arc("burn", 1), Arc("coast", 3), Arc("burn", 2), Arc("coast", 2)),
                 (1e-12, 0.1, 0.3, 1e-13, 0.6 - 2e-12), 10, True)
    out = without_short_arcs(lay, 1e-9)
    # the leading sliver goes to the first kept arc; the middle burn vanishes and its coasts merge
    assert [a.kind for a in out.arcs] == ["burn", "coast"] and [a.segments for a in out.arcs] == [1, 5]
    assert sum(out.sigma) == pytest.approx(sum(lay.sigma), abs=1e-15)
    assert without_short_arcs(out, 1e-9) is None


@pytest.mark.slow
def test_fixed_tf_6000_is_infeasible_not_unconverged():
    # tf = 6000 s (issue 15): the cheapest single impulse, 3883.8 m/s (366 kg of 400), flies through
    # the Earth (its arc's periapsis is below 3000 km).  Its finite-thrust neighbour then failed as
    # not_converged (a 2200 km re-propagation miss: collocation cannot follow a dive next to the
    # Earth's centre).  Leaving such arcs out, the cheapest admissible single impulse needs 6274 m/s,
    # 441 kg: more than on board; the finite-thrust solve is infeasible and says so.
    from solvers.intercept import solve

    sol = solve(InterceptProblem(replace(PAPER_003, tf_s=6000.0), methods=("impulsive", "finite_thrust")))
    assert sol.impulsive.status.outcome is Outcome.INFEASIBLE
    assert sol.impulsive.fuel_kg == pytest.approx(440.7, abs=0.1)
    ft = sol.finite_thrust
    assert ft.status.outcome is Outcome.INFEASIBLE, ft.status
    assert "400 kg of propellant" in ft.status.message and "tf = 6000 s" in ft.status.message
    assert sol.status.outcome is Outcome.INFEASIBLE
    # the outcome follows from the impulsive bound, not from how IPOPT stopped on this CPU
    assert ft.status.solver_status == "insufficient_propellant"
    assert ft.status.details["impulsive_bound_fuel_kg"] == pytest.approx(440.7, abs=0.1)


@pytest.mark.parametrize("ipopt_status, outcome, expected", [
    ("Maximum_Iterations_Exceeded", Outcome.NOT_CONVERGED, Outcome.INFEASIBLE),   # another CPU's iterates
    ("Infeasible_Problem_Detected", Outcome.INFEASIBLE, Outcome.INFEASIBLE),
    ("Restoration_Failed", Outcome.NOT_CONVERGED, Outcome.INFEASIBLE),
    # converged but the re-propagation misses: a feasible NLP point, never called infeasible
    ("Solve_Succeeded", Outcome.NOT_CONVERGED, Outcome.NOT_CONVERGED),
    ("Solve_Succeeded", Outcome.OPTIMAL, Outcome.OPTIMAL),
])
def test_a_failed_finite_thrust_solve_is_classified_by_the_impulsive_bound(ipopt_status, outcome, expected):
    from solvers.intercept import by_impulsive_bound
    from solvers.intercept.thrust import FiniteThrustSolution

    imp = solve_impulsive(InterceptProblem(replace(PAPER_003, tf_s=6000.0)))
    assert imp.status.solver_status == "insufficient_propellant"
    sol = by_impulsive_bound(FiniteThrustSolution(status=SolveStatus(outcome, solver_status=ipopt_status)), imp,
                             replace(PAPER_003, tf_s=6000.0))
    assert sol.status.outcome is expected
    # with enough propellant the bound says nothing and a failure stays what IPOPT said
    roomy = replace(imp, status=SolveStatus(Outcome.OPTIMAL, solver_status="Scan_Refined"))
    sol = by_impulsive_bound(FiniteThrustSolution(status=SolveStatus(outcome, solver_status=ipopt_status)), roomy,
                             replace(PAPER_003, tf_s=6000.0))
    assert sol.status.outcome is outcome


@pytest.mark.slow
def test_verification_reports_the_smallest_radius_and_the_planet():
    from tests.preset_results import solve_preset

    _, _, out = solve_preset("long-range-intercept")
    ver = out.result["finite_thrust"]["verification"]
    # the paper answer stays above the surface: its lowest point is the target's own orbit region
    assert ver["through_planet"] is False and 6378137.0 < ver["min_radius_m"] < 6878137.0 + 1.0
    assert not any("passes through the planet" in n for n in out.result["notes"])
    # tf = 6000 s with the through-planet arcs kept: the warm start dives through the Earth and so
    # does the finite-thrust trajectory; the verification says so (and the solve is not converged)
    from solvers.intercept import solve

    sol = solve(InterceptProblem(replace(PAPER_003, tf_s=6000.0), methods=("impulsive", "finite_thrust"),
                                 scan=ScanSettings(exclude_through_planet=False)))
    assert sol.finite_thrust.verification["through_planet"] is True
    assert sol.finite_thrust.verification["min_radius_m"] < 6378137.0


@pytest.mark.slow
def test_cheapest_impulse_above_the_propellant_on_board_is_infeasible():
    # Issue 25: a cheapest admissible impulse of 682 kg with 600 kg on board (774 kg wet at tf = 6000 s)
    # ends infeasible, whatever IPOPT's iterates do on this CPU (the impulsive bound decides).
    from solvers.intercept import solve

    sn = replace(PAPER_003, tf_s=6000.0, mass_kg=774.0, propellant_kg=600.0)
    sol = solve(InterceptProblem(sn, methods=("impulsive", "finite_thrust")))
    assert sol.impulsive.status.outcome is Outcome.INFEASIBLE
    assert sol.impulsive.fuel_kg == pytest.approx(682.2, abs=0.5)
    ft = sol.finite_thrust
    assert ft.status.outcome is Outcome.INFEASIBLE, ft.status
    assert ft.status.solver_status == "insufficient_propellant" and "600 kg of propellant" in ft.status.message
    assert sol.status.outcome is Outcome.INFEASIBLE


@pytest.mark.parametrize("upper", [7500.0, 8000.0])
@pytest.mark.slow
def test_a_study_row_states_no_time_outside_its_bounds(upper):
    # Issue 25 item 4: fuel-vs-intercept-time rows whose allowed time ends before 8080.5 s showed the
    # impulsive answer at 8080.5 s; the impulsive method now answers within the row's own bounds.
    from app.service.params import deep_merge
    from app.kinds.intercept import PRESETS, SPEC, run
    from app.service.study_presets import STUDY_PRESETS
    from tests.support import RecordingContext

    study = STUDY_PRESETS["fuel-vs-intercept-time"]
    base = next(p for p in PRESETS if p.name == study["preset"]).params
    params = deep_merge(deep_merge(base, study["params"]), {"tf_bounds_s": [2000.0, upper]})
    out = run(SPEC.params_model.model_validate(params), RecordingContext())
    key = SPEC.key_numbers(out.result)
    times = {k: v for k, v in key.items() if k.endswith("tf_s") and v is not None}
    assert {"impulsive.tf_s", "finite_thrust.tf_s"} <= set(times)
    assert all(2000.0 <= v <= upper for v in times.values()), times
