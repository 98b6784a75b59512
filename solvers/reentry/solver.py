"""Lifting reentry trajectory optimization by direct multiple shooting (the ``reentry`` job kind).

Problem: paper 000 (Qu Xiangju, "Application of direct multiple shooting to trajectory
optimization", 1991), cases 1-4, and the Betts shuttle benchmark (Betts, *Practical Methods for
Optimal Control*, 2nd ed., sec. 6.3: max final latitude, with and without the 70 BTU/ft^2/s
heating limit).  Dynamics and vehicle: :mod:`solvers.models.reentry_dynamics`,
:mod:`solvers.models.shuttle`; the state (names, units, scales, bounds):
:mod:`solvers.models.reentry_state`; initial guesses: :mod:`solvers.reentry.guess`; transcription:
:mod:`solvers.transcription.multiple_shooting`; independent check: :mod:`solvers.verification`.

Objectives (all in SI/radians, minimized internally):
``max_crossrange`` (final latitude), ``max_downrange`` (final longitude), ``max_great_circle_range``
(paper 000 eqs. 24-26; degenerate for the shuttle, whose glide reaches the antipode),
``min_heat_load`` (paper 000 case 3: ``int sqrt(rho) v^3 dt``), ``min_time``.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import time

import numpy as np

from solvers.common import Outcome, ProgressFn, StopFn
from solvers.models.aero_coverage import aero_coverage_notes
from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.models.reentry_state import ALPHA, LATITUDE, LONGITUDE, NX, STATES, X_SCALE
from solvers.transcription.multiple_shooting import Transcription, control_at
from solvers.reentry.guess import InitialGuess, linear_guess, on_grid, simulate_constant_controls
from solvers.reentry.limits import hold_problem_limits, limit_checks, path_limits
from solvers.reentry import terminal as term
from solvers.reentry.certificate import certified_infeasible, infeasible_before_the_nlp
from solvers.reentry.minmax import classify_by_least_peak, coarse_least_peak
from solvers.reentry.problem import ReentryProblem, ReentrySolution
from solvers.reentry.shooting import param_vector, shooting_problem, state_bounds
from solvers.reentry.stages import PLAN, ROUND_PLAN
from solvers.progress import Progress
from solvers.verification import Verification, propagate_dense

def objective_value(problem: ReentryProblem, tf: float, x: np.ndarray, u_nodes: np.ndarray,
                    t: np.ndarray) -> tuple[float, str]:
    """The objective in natural units: (value, unit)."""
    obj = problem.objective
    if obj == "max_crossrange":
        return float(x[LATITUDE, -1]), "rad"
    if obj == "max_downrange":
        return float(x[LONGITUDE, -1]), "rad"
    if obj == "max_great_circle_range":
        lon0, lat0 = problem.initial_state[LONGITUDE], problem.initial_state[LATITUDE]
        latf, lonf = x[LATITUDE, -1], x[LONGITUDE, -1]
        c = math.sin(lat0) * math.sin(latf) + math.cos(lat0) * math.cos(latf) * math.cos(lonf - lon0)
        return float(math.acos(max(-1.0, min(1.0, c)))), "rad"
    if obj == "min_heat_load":
        return float(np.trapezoid(dyn.stagnation_heat_integrand(x, problem.vehicle, np), t)), \
            "kg^0.5 m^1.5 s^-2"
    return float(tf), "s"


def path_quantities(vehicle: sh.Vehicle) -> dict:
    """The path quantities a verification reports, ``name -> fn(X, U)`` on (NX, N) arrays."""
    return {"heat_rate_w_m2": lambda X, U: dyn.heat_rate(X, U, vehicle, np),
            "dynamic_pressure_pa": lambda X, U: dyn.dynamic_pressure(X, vehicle, np),
            "load_factor": lambda X, U: dyn.load_factor(X, U, vehicle, np)}


def _physical_violation(problem: ReentryProblem, tr: Transcription, res) -> str:
    """Describe the worst violated constraint of an NLP iterate in physical units."""
    blocks = tr.constraint_blocks(res.nlp.g)
    parts = []
    mm = blocks["matching"].reshape((NX, -1), order="F") * np.asarray(X_SCALE)[:, None]
    rel = np.abs(mm) / np.asarray(X_SCALE)[:, None]
    i, j = np.unravel_index(int(np.argmax(rel)), rel.shape)
    comp = STATES[i]
    name = comp.label
    f, unit = (1 / sh.DEG, "deg") if comp.is_angle else (1.0, comp.unit)
    parts.append(f"worst matching defect: {name} {abs(mm[i, j]) * f:.4g} {unit} at interval {j}")
    if j == mm.shape[1] - 1:
        # The last interval's integrated end is where the flight actually gets to.
        reached = (res.x[i, -1] + mm[i, j]) * f
        parts.append(f"the flight reaches {name} {reached:.4g} {unit} where the terminal "
                     f"condition asks {res.x[i, -1] * f:.4g} {unit}")
    if "path_nodes" in blocks and blocks["path_nodes"].size:
        worst = float(blocks["path_nodes"].max())
        if worst > 0:
            parts.append(f"worst path-limit excess {100 * worst:.3g}% of its limit")
    return "; ".join(parts)


def solve(problem: ReentryProblem, *, initial_guess: InitialGuess | str | None = None,
          on_progress: ProgressFn | Progress | None = None, should_stop: StopFn | None = None,
          seed=None) -> ReentrySolution:  # seed unused: deterministic
    """Solve one reentry problem. ``initial_guess``: an :class:`InitialGuess` (warm start, any
    grid), ``"linear"``, ``"simulate"`` or None (the default: simulate).  ``on_progress``: the job's
    callback, or the nested stages of a refinement round (:mod:`solvers.progress`)."""
    m = problem.intervals
    notes: list[str] = []
    stages: list[dict] = []
    # a refinement round hands in its own nested stages; a job's own solve declares the whole plan
    own = not isinstance(on_progress, Progress)
    progress = on_progress if isinstance(on_progress, Progress) else Progress(on_progress, PLAN)
    has_path = any(v is not None for v in (problem.max_heat_rate_w_m2,
                                           problem.max_dynamic_pressure_pa, problem.max_load_factor))
    if isinstance(initial_guess, InitialGuess):
        guess = initial_guess
    elif initial_guess == "simulate":
        guess = simulate_constant_controls(problem, alpha_rad=17.0 * sh.DEG, bank_rad=-60.0 * sh.DEG)
    elif initial_guess == "linear":
        guess = linear_guess(problem)
    else:
        # A constant-control glide is a physical trajectory (all matching conditions hold), from
        # which IPOPT needs ~15 iterations on the Betts case; straight lines need ~90.
        guess = simulate_constant_controls(problem, alpha_rad=17.0 * sh.DEG, bank_rad=-60.0 * sh.DEG)
    proved = certified_infeasible(problem, guess) if has_path else None
    if proved is not None:
        # Proved before any iteration (solvers.reentry.certificate): the outcome rests on the problem.
        return proved
    if problem.max_heat_rate_w_m2 is not None and not isinstance(initial_guess, InitialGuess):
        # A limit both ends keep but no flight between can: the least peak on coarse grids
        # (solvers.reentry.minmax) decides in seconds what the limited NLP took ~50 s to fail.
        # Skipped on warm starts (refinement rounds, a job's answer): their problem was judged already.
        progress.stage("least peak", message="the least peak heating rate any control gives")
        cert = coarse_least_peak(problem, guess, should_stop=should_stop)
        if cert is not None:
            stages += [{"stage": f"least peak heating, {g['intervals']} intervals", "status": g["status"],
                        "iterations": g["iterations"], "solve_time_s": g["solve_time_s"]} for g in cert["grids"]]
        if cert is not None and cert["proves_infeasible"]:
            return _least_peak_infeasible(problem, guess, cert, stages)
    if problem.terminal.latitude_rad is not None or problem.terminal.longitude_rad is not None:
        # A terminal position may be out of reach (paper 000 case 4). Telling IPOPT to expect
        # infeasibility makes it enter restoration early and stop at a point of minimal
        # infeasibility within ~40 iterations, instead of wandering for hundreds; on feasible
        # problems of this kind it costs a few iterations.
        problem = dataclasses.replace(problem, ipopt={"expect_infeasible_problem": "yes",
                                                      **problem.ipopt})
    p = param_vector(problem)
    x_lb, x_ub, u_lb, u_ub = state_bounds(problem, m)
    build_time = 0.0
    warm_internally = has_path and not isinstance(initial_guess, InitialGuess)
    if warm_internally:
        # Pitfall seen (spec): the heat-limited case converges badly from a cold guess; solve the
        # unconstrained problem first and start the constrained one from it.
        tr0 = Transcription(shooting_problem(problem, with_path=False))
        build_time += 0.0 if tr0.was_cached else tr0.solver.build_time_s
        r0 = tr0.solve(p=p, x_lb=x_lb, x_ub=x_ub, u_lb=u_lb, u_ub=u_ub,
                       tf_bounds=problem.tf_bounds_s, guess=on_grid(guess, m, problem.control),
                       on_progress=progress.stage("solve without path limits"), should_stop=should_stop,
                       expected_iterations=40)
        stages.append({"stage": "without path limits", "status": r0.status.solver_status,
                       "iterations": r0.status.iterations, "solve_time_s": r0.status.solve_time_s})
        if r0.status.outcome is Outcome.CANCELLED:
            return _solution(problem, tr0, r0, build_time, notes, stages)
        if r0.status.ok:
            guess = InitialGuess(t=r0.t, x=r0.x, u=_u_at_nodes(r0.t, r0.u, problem.control))
            notes.append("warm-started from the solution without path limits")
    if isinstance(guess, InitialGuess) and (warm_internally or isinstance(initial_guess, InitialGuess)):
        # From a converged neighbour the adaptive barrier update restarts far from the boundary
        # (136 iterations on the heat-limited case); a small fixed barrier keeps the warm start
        # (20 iterations).
        problem = dataclasses.replace(problem, ipopt={**WARM_IPOPT, **problem.ipopt})
    timer = {"s": 0.0, "build": build_time}
    run = functools.partial(_solve_held, p=p, bounds=(x_lb, x_ub, u_lb, u_ub), stages=stages, timer=timer,
                            should_stop=should_stop)
    tr, res, ver, report = run(problem, on_grid(guess, m, problem.control), "full problem", progress)
    terminal = None
    if ver is not None:
        problem, tr, res, ver, report, terminal = _hold_terminal(problem, tr, res, ver, report, run, progress)
    sol = _solution(problem, tr, res, timer["build"], notes, stages, ver=ver, report=report,
                    terminal=terminal, verification_time_s=timer["s"])
    if sol.status.outcome is Outcome.NOT_CONVERGED and problem.max_heat_rate_w_m2 is not None:
        classify_by_least_peak(problem, sol, sp=shooting_problem(problem), p=p, bounds=(x_lb, x_ub, u_lb, u_ub),
                               guess=on_grid(guess, m, problem.control), should_stop=should_stop)
    if own:
        progress.stage("answer")
        progress.done(sol.status.outcome.value)
    return sol


def _least_peak_infeasible(problem, guess, cert, stages) -> ReentrySolution:
    limit, least, err = cert["limit_w_m2"], cert["least_peak_heat_rate_w_m2"], cert["error_estimate_w_m2"]
    coarse = cert["grids"][0]["least_peak_heat_rate_w_m2"]
    msg = (f"the least peak heating rate any control gives is {least:.6g} W/m^2 (a min-max solve on "
           f"{cert['grids'][-1]['intervals']} intervals; {coarse:.6g} on {cert['grids'][0]['intervals']}, so "
           f"the grid's error is at most about {err:.3g}), above the limit {limit:.6g} "
           f"({100 * (least / limit - 1):+.1f}%) by more than that error and the limit's tolerance")
    return infeasible_before_the_nlp(problem, guess, solver_status="least_peak_bound",
                                     message=f"infeasible, shown before the limited NLP: {msg}",
                                     violation=least / limit - 1.0,
                                     details={"least_peak_certificate": cert, "least_peak_heat_rate_w_m2": least},
                                     note=f"the limited NLP was not solved: {msg}", stages=stages)


WARM_IPOPT = {"mu_strategy": "monotone", "mu_init": 1e-3}


def _solve_held(problem, guess, stage, progress: Progress, *, p, bounds, stages, timer, should_stop):
    """One solve of ``problem`` from ``guess`` (on its grid), verified and its path limits held, each
    a stage of ``progress``: ``(transcription, result, verification or None, limit report or None)``."""
    x_lb, x_ub, u_lb, u_ub = bounds
    tr = Transcription(shooting_problem(problem))
    timer["build"] += 0.0 if tr.was_cached else tr.solver.build_time_s
    res = tr.solve(p=p, x_lb=x_lb, x_ub=x_ub, u_lb=u_lb, u_ub=u_ub, tf_bounds=problem.tf_bounds_s,
                   guess=guess, on_progress=progress.stage("solve"), should_stop=should_stop,
                   expected_iterations=40)
    stages.append({"stage": stage, "status": res.status.solver_status,
                   "iterations": res.status.iterations, "solve_time_s": res.status.solve_time_s})
    ver, report = None, None
    if problem.verify and res.status.outcome is Outcome.OPTIMAL:
        def verify(r):
            t0 = time.perf_counter()
            out = _verify(problem, tr, r, p)
            timer["s"] += time.perf_counter() - t0
            return out
        progress.stage("verification", message="the dense re-propagation")
        ver = verify(res)
        limits = path_limits(problem)
        if limits and problem.limit_tolerance is None:
            ver.limits = limit_checks(ver, limits, 0.0)     # report only
        elif limits:
            res, ver, report = hold_problem_limits(
                problem, tr, res, ver, p=p, param_vector=param_vector, limits=limits, verify=verify,
                bounds=bounds, stages=stages, progress=progress, should_stop=should_stop)
    return tr, res, ver, report


def _hold_terminal(problem, tr, res, ver, report, run, progress: Progress):
    """Terminal conditions that hold (:mod:`solvers.reentry.terminal`): re-solve with more substeps,
    warm from the previous answer on the same grid, until the re-propagated final state meets every
    requested value; returns the best round's ``(problem, tr, res, ver, report, rounds)``."""
    requested = problem.terminal.as_array()
    tol = problem.terminal_tolerance or term.TerminalTolerance()
    ver.terminal = term.terminal_checks(requested, ver, tol)
    rounds = [term.round_record(problem.substeps, ver.terminal)]
    limits_ok = report is None or report.held
    if problem.terminal_tolerance is None or not limits_ok:
        # Report only; an answer whose path limits fail has failed already (limit_not_held).
        return problem, tr, res, ver, report, rounds
    best = (not limits_ok, rounds[0]["worst_ratio"], problem, tr, res, ver, report)
    while rounds[-1]["worst_ratio"] > 1.0 and len(rounds) <= problem.terminal_rounds:
        n = term.next_substeps(problem.substeps, rounds[-1]["worst_ratio"])
        if n == problem.substeps:
            break
        problem = dataclasses.replace(problem, substeps=n, ipopt={**WARM_IPOPT, **problem.ipopt})
        guess = (res.tf, res.x, res.u)
        k = len(rounds)
        tr, res, ver, report = run(problem, guess, f"terminal round {k} ({n} substeps)",
                                   progress.within("terminal", ROUND_PLAN, round=k))
        if ver is None:
            break
        ver.terminal = term.terminal_checks(requested, ver, tol)
        rounds.append(term.round_record(n, ver.terminal))
        cand = (not (report is None or report.held), rounds[-1]["worst_ratio"], problem, tr, res, ver, report)
        if cand[:2] <= best[:2]:
            best = cand
    _, _, problem, tr, res, ver, report = best
    return problem, tr, res, ver, report, rounds


def _verify(problem: ReentryProblem, tr: Transcription, res, p) -> Verification:
    """The dense re-propagation of an answer with the transcription's own dynamics and data."""
    sp = tr.prob
    return propagate_dense(dynamics=sp.dynamics, p=p, key=sp.key, x0=problem.initial_state,
                           t_nodes=res.t, x_nodes=res.x, u_nodes=res.u, control=problem.control,
                           path=path_quantities(problem.vehicle),
                           samples_per_interval=problem.verify_samples)


def _u_at_nodes(t, u, control):
    return control_at(t, t, u, control)


def _solution(problem, tr, res, build_time, notes, stages, *, ver=None, report=None, terminal=None,
              verification_time_s=0.0) -> ReentrySolution:
    st = res.status
    total_iter = sum(s["iterations"] for s in stages)
    total_solve = sum(s["solve_time_s"] for s in stages)
    status = dataclasses.replace(st, iterations=total_iter, solve_time_s=total_solve,
                                 build_time_s=build_time,
                                 details={**st.details, "stages": stages,
                                          "solver_cached": tr.was_cached})
    if st.outcome is not Outcome.OPTIMAL and st.outcome is not Outcome.CANCELLED:
        status.message = (f"IPOPT: {st.solver_status} after {st.iterations} iterations; "
                          f"{_physical_violation(problem, tr, res)}")
    u_nodes = _u_at_nodes(res.t, res.u, problem.control)
    q = dyn.heat_rate(res.x, u_nodes, problem.vehicle, np)
    value, unit = objective_value(problem, res.tf, res.x, u_nodes, res.t)
    if ver is not None:
        status.details["verification_time_s"] = verification_time_s
    if ver is not None and report is None and problem.limit_tolerance is None:
        notes += [f"{q} is enforced at the {problem.path_enforcement}; between them the "
                  f"re-propagated trajectory exceeds its limit by {100 * c['excess']:.2f}% "
                  f"(worst {c['max']:.6g})" for q, c in ver.limits.items() if not c["held"]]
    if report is not None:
        status.details["limit_rounds"] = report.rounds
        notes.append(f"the path limits are enforced at the {problem.path_enforcement} of the NLP; "
                     + report.summary())
        if report.cancelled and status.outcome is Outcome.OPTIMAL:
            status.outcome, status.message = Outcome.CANCELLED, "cancelled during the limit rounds"
        elif not report.held and status.outcome is Outcome.OPTIMAL:
            status.outcome = Outcome.LIMIT_NOT_HELD
            bad = {q: c for q, c in ver.limits.items() if not c["held"]}
            status.message = ("path limit not held between the nodes: " + "; ".join(
                f"{q} reaches {c['max']:.6g} against the limit {c['limit']:.6g} "
                f"({100 * c['excess']:+.3f}%, tolerance {100 * problem.limit_tolerance:g}%) at "
                f"t = {c['max_t_s']:.1f} s" for q, c in bad.items())
                + f" after {len(report.rounds) - 1} tightening round(s) (limit_rounds "
                f"{problem.limit_rounds}); the best answer is stored as the diagnostic")
    if terminal is not None:
        _terminal_verdict(problem, status, ver, terminal, notes)
    notes += aero_coverage_notes(problem.vehicle, res.x, u_nodes[ALPHA], alpha_bounds_rad=problem.alpha_bounds_rad)
    return ReentrySolution(status=status, objective_name=problem.objective, objective_value=value,
                           objective_unit=unit, tf_s=res.tf, t=res.t, x=res.x, u=res.u, u_nodes_at_t=u_nodes,
                           heat_rate=np.asarray(q, float), verification=ver, notes=notes,
                           stages=stages)


def _terminal_verdict(problem, status, ver, rounds, notes) -> None:
    """Note the terminal check and fail an otherwise optimal answer that misses a requested final value."""
    status.details["terminal_rounds"] = rounds
    if not ver.terminal:
        return
    notes.append(f"the NLP integrates with {problem.substeps} RK4 substeps per interval; "
                 + term.summary(ver.terminal, rounds))
    missed = not all(c["held"] for c in ver.terminal.values())
    if status.outcome is Outcome.OPTIMAL and missed and problem.terminal_tolerance is not None:
        status.outcome = Outcome.TERMINAL_NOT_HELD
        status.message = ("terminal conditions not held on the dense re-propagation: "
                          + term.summary(ver.terminal, rounds).split("miss: ", 1)[1]
                          + f" after {len(rounds) - 1} refinement round(s) (terminal_rounds "
                          f"{problem.terminal_rounds}); the best answer is stored as the diagnostic")
