"""Long-range interception (paper 003): problem, methods, and the one entry point.

Scenario and methods: paper 003 (optimal long-range interception, 2011),
spec ``shared/specs/intercept.md``.  The problem and solutions are in
:mod:`solvers.intercept.problem`; this module holds Method II, the impulsive single-burn interception:
coast the interceptor on its orbit to the maneuver time ``t_man``, apply one
impulse that puts it on the Lambert arc reaching the target's position at the
fixed interception time ``t1``; delta-v(t_man) = |v_lambert - v_coast|
(paper sec. 3, "fixed-time interception theorem").  The scan over ``t_man`` is
one batched Lambert call per branch (direction, revolutions, path); the best
grid point is then refined with a bounded scalar minimization.  Fuel follows
the rocket equation ``m0 (1 - exp(-dv / (Isp g0)))``.  Lambert arcs that pass
through the planet are left out by default (``ScanSettings.exclude_through_planet``;
the branches and their delta-v: :mod:`solvers.intercept.branches`; the porkchop
map: :mod:`solvers.intercept.porkchop`).

The paper uses Battin-Vaughan's Lambert algorithm and reports 1501.73 m/s at
4328 s; with its printed elements the model gives 2302.48 m/s at 3142.5 s
(prograde, zero revolutions), see the spec.  Its delta-v vector applied at
4328 s does not reach the target, so the paper's figure cannot be reproduced.

``solve`` dispatches over ``problem.methods``; a method is a function
``(problem, *, on_progress, should_stop, initial_guess, earlier) -> <Method>Solution``
registered in ``METHODS`` (``earlier``: the impulsive solution when it ran
first; the finite-thrust method lives in ``solvers/intercept/thrust/`` and
starts from the impulsive answer).
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import Callable

import numpy as np
from scipy.optimize import minimize_scalar

from solvers.astro.kepler import propagate
from solvers.common import Outcome, ProgressFn, SolveStatus, StopFn, never_stop, noop_progress
from solvers.intercept.branches import Branch, branches, delta_v
from solvers.intercept.porkchop import PorkchopSettings, porkchop_map
from solvers.intercept.problem import ImpulsiveSolution, InterceptProblem, InterceptSolution, ScanSettings
from solvers.intercept.thrust import FiniteThrustProblem, FiniteThrustSolution, ImpulsiveGuess, solve_finite_thrust


def _branches(scan: ScanSettings) -> list[Branch]:
    return branches(max_revolutions=scan.max_revolutions, retrograde=scan.retrograde)


def solve_impulsive(problem: InterceptProblem, *, on_progress: ProgressFn | None = None,
                    should_stop: StopFn | None = None) -> ImpulsiveSolution:
    """Method II: single-impulse interception at fixed time, Lambert scan + refinement."""
    progress = on_progress or noop_progress
    stop = should_stop or never_stop
    t_start = time.perf_counter()
    sn = problem.scenario
    mu, t1 = sn.mu_m3_s2, sn.tf_s
    scan = problem.scan
    r0i, v0i, r0t, v0t = sn.initial_states()
    r_t1, v_t1 = propagate(mu, r0t, v0t, t1)

    t_end = t1 if scan.t_end_s is None else min(scan.t_end_s, t1)
    grid = np.arange(scan.t_start_s, t_end, scan.step_s)
    searched = _branches(scan)
    n = grid.size
    dv_all = np.full((len(searched), n), np.nan)
    through = np.zeros((len(searched), n), bool)
    empty = ImpulsiveSolution(
        status=SolveStatus(Outcome.FAILED), t_man_s=grid, delta_v_mps=np.full(n, np.nan),
        branch_index=np.full(n, -1), branches=searched, tf_s=t1)
    if n == 0:
        empty.status = SolveStatus(Outcome.FAILED, solver_status="empty_window",
                                   message="the maneuver window [t_start, min(t_end, t1)) is empty")
        return empty

    r_m, v_m = propagate(mu, r0i, v0i, grid)
    for k, branch in enumerate(searched):
        if stop():
            empty.status = SolveStatus(Outcome.CANCELLED, solver_status="cancelled",
                                       message="cancelled during the Lambert scan")
            return empty
        bdv = delta_v(mu, r_m, v_m, r_t1, t1 - grid, branch, body_radius_m=scan.excluded_below_m)
        dv_all[k] = np.linalg.norm(bdv.delta_v_mps, axis=1)
        through[k] = bdv.through_planet
        progress(0.8 * (k + 1) / len(searched), f"Lambert scan: {branch.label()} ({n} maneuver times)")

    finite = np.isfinite(dv_all)
    any_ok = finite.any(axis=0)
    branch_index = np.where(any_ok, np.argmin(np.where(finite, dv_all, np.inf), axis=0), -1)
    curve = np.where(any_ok, np.min(np.where(finite, dv_all, np.inf), axis=0), np.nan)
    sol = ImpulsiveSolution(status=SolveStatus(Outcome.FAILED), t_man_s=grid, delta_v_mps=curve,
                            branch_index=branch_index, branches=searched, tf_s=t1,
                            excluded_through_planet=int(through.sum()),
                            points_only_through_planet=int(np.count_nonzero(~any_ok & through.any(axis=0))))
    if not any_ok.any():
        msg = "no Lambert branch reaches the target from any maneuver time"
        if sol.excluded_through_planet:
            msg += (f" without passing through the planet ({sol.excluded_through_planet} solutions below "
                    f"{scan.body_radius_m:.0f} m left out; scan.exclude_through_planet: false keeps them)")
        sol.status = SolveStatus(Outcome.INFEASIBLE, solver_status="no_lambert_solution", message=msg,
                                 solve_time_s=time.perf_counter() - t_start)
        return sol

    kbest = int(np.nanargmin(curve))
    branch = searched[int(branch_index[kbest])]
    t_best, dv_best = float(grid[kbest]), float(curve[kbest])
    iterations = 0
    if scan.refine:
        lo = max(scan.t_start_s, t_best - scan.step_s)
        hi = min(t_end, t_best + scan.step_s)
        hi = min(hi, np.nextafter(t1, -np.inf))  # tof = 0 is singular

        def objective(tm: float) -> float:
            r, v = propagate(mu, r0i, v0i, tm)
            val = float(np.linalg.norm(delta_v(mu, r, v, r_t1, t1 - tm, branch,
                                               body_radius_m=scan.excluded_below_m).delta_v_mps))
            return val if np.isfinite(val) else 1e30

        if hi > lo:
            res = minimize_scalar(objective, bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-4})
            iterations = int(res.nfev)
            if res.success and res.fun <= dv_best:
                t_best, dv_best = float(res.x), float(res.fun)
    progress(0.9, "refined the best maneuver time")

    r_b, v_b = propagate(mu, r0i, v0i, t_best)
    best = delta_v(mu, r_b, v_b, r_t1, t1 - t_best, branch, body_radius_m=None)
    dvec = best.delta_v_mps
    v_after = v_b + dvec
    # independent check: coast the post-burn state to t1 and compare with the target
    r_chk, _ = propagate(mu, r_b, v_after, t1 - t_best)
    sol.best_t_man_s = t_best
    sol.best_delta_v_mps = dv_best
    sol.delta_v_vector_mps = dvec
    sol.fuel_kg = float(sn.fuel_kg(dv_best))
    sol.best_branch = branch
    sol.burn_position_m = r_b
    sol.velocity_before_mps = v_b
    sol.velocity_after_mps = v_after
    sol.relative_velocity_at_intercept_mps = best.v_arrival_mps - v_t1
    sol.miss_distance_m = float(np.linalg.norm(r_chk - r_t1))

    if problem.porkchop is not None:
        sol.porkchop = porkchop_map(problem.porkchop, mu=mu, t1=t1, interceptor=(r0i, v0i), target=(r0t, v0t),
                                    branches=searched, body_radius_m=scan.excluded_below_m)
        progress(0.95, f"porkchop {problem.porkchop.t_man_points} x {problem.porkchop.t_intercept_points}")

    elapsed = time.perf_counter() - t_start
    details = {"branch": branch.label(), "grid_points": int(n),
               "refine_evaluations": iterations, "miss_distance_m": sol.miss_distance_m,
               "excluded_through_planet": sol.excluded_through_planet}
    if sol.fuel_kg > sn.propellant_kg:
        sol.status = SolveStatus(
            Outcome.INFEASIBLE, solver_status="insufficient_propellant",
            message=(f"best single burn needs {sol.fuel_kg:.1f} kg of propellant, "
                     f"only {sn.propellant_kg:.1f} kg on board"),
            iterations=iterations, solve_time_s=elapsed, details=details)
    else:
        sol.status = SolveStatus(Outcome.OPTIMAL, solver_status="Scan_Refined",
                                 message=f"minimum {dv_best:.2f} m/s at t_man {t_best:.2f} s ({branch.label()})",
                                 iterations=iterations, solve_time_s=elapsed, details=details)
    progress(1.0, "impulsive scan done")
    return sol


def best_intercept_time(problem: InterceptProblem) -> float:
    """The interception time of the best single impulse: ``tf_s`` when it is fixed; with a free final
    time the best point of a maneuver x interception-time map over the tf bounds (delta-v is multimodal
    in tf: the geometry repeats with the target's period), ``tf_s`` clipped into them when none reaches."""
    sn = problem.scenario
    if not sn.free_final_time:
        return sn.tf_s
    lo, hi = sn.tf_bounds_s
    base = replace(problem, porkchop=None, scan=replace(problem.scan, t_end_s=None, t_start_s=0.0))
    r0i, v0i, r0t, v0t = sn.initial_states()
    settings = PorkchopSettings(t_man_points=240, t_intercept_points=int(np.clip((hi - lo) / 60.0, 40, 400)) + 1,
                                t_man_min_s=0.0, t_man_max_s=hi, t_intercept_min_s=lo, t_intercept_max_s=hi)
    pc = porkchop_map(settings, mu=sn.mu_m3_s2, t1=sn.tf_s, interceptor=(r0i, v0i), target=(r0t, v0t),
                      branches=_branches(base.scan), body_radius_m=base.scan.excluded_below_m)
    if np.isfinite(pc.best_t_intercept_s):
        return float(min(max(pc.best_t_intercept_s, lo), hi))
    return float(min(max(sn.tf_s, lo), hi))


def _impulsive_start(problem: InterceptProblem, earlier: ImpulsiveSolution | None, progress, stop):
    """Warm start for the finite-thrust method: ``(ImpulsiveGuess, tf_s, impulsive solution)``.

    Fixed tf: the impulsive optimum at the same interception time (reused if
    the impulsive method already ran).  Free tf: the best single impulse over
    the tf bounds, found on a maneuver x interception-time map; delta-v is
    multimodal in tf (the geometry repeats with the target's period), so a
    local NLP started elsewhere would keep the nearest local optimum.
    """
    sn = problem.scenario
    base = replace(problem, porkchop=None, scan=replace(problem.scan, t_end_s=None, t_start_s=0.0))
    tf = best_intercept_time(problem)
    if sn.free_final_time:
        earlier = None     # found on the map with the warm start's own scan step
    if earlier is None or not earlier.status.ok or abs(earlier.tf_s - tf) > 1e-9:
        earlier = solve_impulsive(replace(base, scenario=replace(sn, tf_s=tf), scan=replace(base.scan, step_s=5.0)),
                                  should_stop=stop)
    if not np.all(np.isfinite(earlier.delta_v_vector_mps)):
        return None, tf, earlier
    return ImpulsiveGuess(earlier.best_t_man_s, earlier.delta_v_vector_mps), tf, earlier


def solve_finite(problem: InterceptProblem, *, on_progress: ProgressFn | None = None,
                 should_stop: StopFn | None = None, initial_guess=None,
                 earlier: ImpulsiveSolution | None = None):
    """Method I (``solvers.intercept.thrust``) on this scenario.

    ``initial_guess``: a ``TrajectoryGuess`` (e.g. from a stored job); without
    one the impulsive answer is the warm start.  ``earlier``: an impulsive
    solution already computed for this problem, reused when it fits.
    """
    progress = on_progress or noop_progress
    tf = problem.scenario.tf_s
    warm = "trajectory of a stored solution"
    imp = None
    if initial_guess is None:
        progress(0.0, "impulsive warm start")
        initial_guess, tf, imp = _impulsive_start(problem, earlier, progress, should_stop)
        if initial_guess is None:
            return FiniteThrustSolution(status=SolveStatus(
                Outcome.INFEASIBLE, solver_status="no_warm_start",
                message="no single-impulse transfer reaches the target, so there is no warm start "
                        f"({imp.status.message})"))
        warm = (f"impulsive optimum: {np.linalg.norm(initial_guess.delta_v_mps):.2f} m/s at "
                f"t_man {initial_guess.t_man_s:.1f} s, interception at {tf:.1f} s")
    fp = FiniteThrustProblem(scenario=replace(problem.scenario, tf_s=tf), mesh=problem.mesh)
    sol = solve_finite_thrust(fp, initial_guess=initial_guess,
                              on_progress=lambda f, m: progress(0.05 + 0.95 * f, m), should_stop=should_stop)
    sol.warm_start = warm
    return by_impulsive_bound(sol, imp, problem.scenario)


def by_impulsive_bound(sol: FiniteThrustSolution, imp: ImpulsiveSolution | None, sn) -> FiniteThrustSolution:
    """An NLP that found no feasible point is ``infeasible`` when the impulsive bound says so.

    IPOPT's way of failing on a problem without a solution depends on its iterates (on one CPU it
    proves local infeasibility, on another it runs out of iterations), so a failed solve's outcome
    cannot rest on IPOPT's return status.  What the problem itself shows decides instead: the
    cheapest admissible single impulse (arcs through the planet left out) already needs more
    propellant than is on board.  That is evidence, not a proof (several burns can cost less than
    one), so it only classifies a solve that found no feasible thrust history; a converged
    solve, which is a proof of feasibility, is never overruled.
    """
    failed = sol.status.outcome in (Outcome.INFEASIBLE, Outcome.NOT_CONVERGED) and sol.status.solver_status not in (
        "Solve_Succeeded", "Solved_To_Acceptable_Level")
    if not failed or imp is None or imp.status.solver_status != "insufficient_propellant":
        return sol
    where = "within the tf bounds" if sn.free_final_time else f"at tf = {sn.tf_s:g} s"
    sol.status = replace(
        sol.status, outcome=Outcome.INFEASIBLE, solver_status="insufficient_propellant",
        message=(f"no thrust history of at most {sn.max_thrust_n:g} N reaches the target {where} with "
                 f"{sn.propellant_kg:g} kg of propellant: the finite-thrust NLP found no feasible point "
                 f"(IPOPT: {sol.status.solver_status}) and the cheapest admissible single impulse needs "
                 f"{imp.fuel_kg:.1f} kg"),
        details={**sol.status.details, "ipopt_status": sol.status.solver_status,
                 "impulsive_bound_fuel_kg": imp.fuel_kg})
    return sol


def _run_impulsive(problem, *, on_progress=None, should_stop=None, initial_guess=None, earlier=None):
    # Free final time: the best single impulse within the tf bounds, so that the impulsive answer is
    # one the bounds allow (issue 25: a study row over the upper bound showed the 8080.5 s answer).
    sn = problem.scenario
    if sn.free_final_time:
        problem = replace(problem, scenario=replace(sn, tf_s=best_intercept_time(problem)))
    return solve_impulsive(problem, on_progress=on_progress, should_stop=should_stop)


METHODS: dict[str, Callable[..., ImpulsiveSolution | FiniteThrustSolution]] = {"impulsive": _run_impulsive, "finite_thrust": solve_finite}


def solve(problem: InterceptProblem, *, initial_guess=None, on_progress: ProgressFn | None = None,
          should_stop: StopFn | None = None, seed=None) -> InterceptSolution:
    """Run every method in ``problem.methods`` in order; the overall status is the worst one.

    ``initial_guess`` (a ``TrajectoryGuess``) warm-starts the finite-thrust
    method; ``seed`` is accepted for the common protocol.
    """
    del seed
    progress = on_progress or noop_progress
    out = InterceptSolution(status=SolveStatus(Outcome.OPTIMAL))
    methods = list(problem.methods)
    worst = None
    for k, name in enumerate(methods):
        if name not in METHODS:
            raise ValueError(f"unknown intercept method {name!r}; known: {sorted(METHODS)}")

        def sub_progress(fraction, message, k=k, name=name):
            progress((k + fraction) / len(methods), f"{name}: {message}")

        res = METHODS[name](problem, on_progress=sub_progress, should_stop=should_stop,
                            initial_guess=initial_guess, earlier=out.impulsive)
        setattr(out, name, res)
        if worst is None or res.status.outcome is not Outcome.OPTIMAL:
            worst = replace(res.status, message=f"{name}: {res.status.message}") if len(methods) > 1 else res.status
        if res.status.outcome is Outcome.CANCELLED:
            break
    if worst is not None:
        out.status = worst
    return out
