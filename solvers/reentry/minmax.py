"""The least peak heating any control can give: a min-max solve that classifies a failed solve.

When the limited NLP fails without IPOPT proving local infeasibility (``Restoration_Failed``,
``Maximum_Iterations_Exceeded``: which of the two depends on the CPU's iterates), the problem itself
is asked instead: minimize the peak of ``q / q_max`` over the flight, with the same dynamics,
bounds and terminal conditions, as an epigraph (a constant extra state ``s`` with
``q / q_max <= s`` at every RK4 step point, ``s_f`` minimized).  That problem always has feasible
points, so it converges where the limited one wanders.  If its least peak exceeds the limit by
more than the limit's tolerance, no control of this transcription keeps the limit: the failed
solve is ``infeasible``, with the least peak in the message.  Like the intercept kind's impulsive
bound it is evidence, not a proof (a local minimum of the min-max problem could lie above the
global one), so it only classifies a solve that found no feasible point; a converged solve is
never overruled, and when the min-max solve does not converge the failure stays what IPOPT said.
The pinned-end bound of :mod:`solvers.reentry.certificate` is the proof, tried first.

The same min-max problem is also solved *before* the limited NLP, on a coarse grid
(:func:`coarse_least_peak`, issue 35 item 8): a limit between the entry's heating and the least
possible peak used to fail only after the limited solve had wandered for ~50 s.  The coarse grid's
own error is measured, not assumed: the min-max is solved on ``COARSE_INTERVALS`` and again, warm,
on twice as many intervals (twice the control freedom and twice the step points where the peak is
sampled); their difference bounds the finer value's error when the values converge at least
linearly.  Only when the finer least peak exceeds the limit by more than that difference plus the
limit's tolerance is the job failed ``infeasible`` up front, with both values stored as the
certificate; otherwise (a feasible limit, or too close to call) the limited NLP decides as before.
"""
from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from solvers.common import Outcome
from solvers.reentry.guess import InitialGuess, on_grid
from solvers.reentry.shooting import param_vector, shooting_problem, state_bounds
from solvers.transcription.multiple_shooting import PathConstraint, ShootingProblem, Transcription, control_at

S_MAX = 100.0   # the epigraph variable's upper bound (peak / limit)


def minmax_problem(sp: ShootingProblem) -> ShootingProblem:
    """The epigraph form of ``sp``'s least peak heating: an extra constant state ``s`` with
    ``q / q_max <= s`` at every RK4 step point, ``s_f`` minimized (``sp``'s ``heat_rate`` path
    constraint is ``q / q_max - 1``).  Block derivatives as the reentry problem's own (equal to
    CasADi's AD, tests/unit/test_transcription_blocks.py), for their speed."""
    heat = next(c for c in sp.path if c.name == "heat_rate")
    nx = sp.nx

    def dynamics(x, u, pp):
        return ca.vertcat(sp.dynamics(x[:nx], u, pp), 0)

    path = (PathConstraint("peak", lambda x, u, pp: heat.fn(x[:nx], u, pp) + 1.0 - x[nx], where="substeps"),)
    return dataclasses.replace(sp, key=("minmax", *sp.key), nx=nx + 1, dynamics=dynamics,
                               x_scale=(*sp.x_scale, 1.0), mayer=lambda xf, T, pp: xf[nx], lagrange=None,
                               objective_scale=1.0, path=path, block_derivatives=True)


def least_peak_ratio(sp: ShootingProblem, *, p, bounds, tf_bounds, guess, should_stop=None,
                     peak_guess: float = 2.0, expected_iterations: int = 60):
    """``(least peak of q / q_max at the step points or None, IPOPT status, result)`` for the reentry
    shooting problem ``sp`` (:func:`minmax_problem`); ``bounds`` and ``guess`` as
    :meth:`Transcription.solve` takes them for ``sp``."""
    nx = sp.nx
    mp = minmax_problem(sp)
    x_lb, x_ub, u_lb, u_ub = bounds
    m1 = x_lb.shape[1]
    x_lb = np.vstack([x_lb, np.zeros((1, m1))])
    x_ub = np.vstack([x_ub, np.full((1, m1), S_MAX)])
    tf, xg, ug = guess
    xg = np.vstack([xg, np.full((1, m1), peak_guess)])
    r = Transcription(mp).solve(p=p, x_lb=x_lb, x_ub=x_ub, u_lb=u_lb, u_ub=u_ub, tf_bounds=tf_bounds,
                                guess=(tf, xg, ug), should_stop=should_stop,
                                expected_iterations=expected_iterations)
    value = float(r.x[nx, -1]) if r.status.outcome is Outcome.OPTIMAL else None
    return value, r.status, r


def classify_by_least_peak(problem, sol, *, sp, p, bounds, guess, should_stop) -> None:
    """A failed heat-limited solve is ``infeasible`` when the least peak any control gives is above
    the limit (module docstring); ``sp``: the problem's shooting problem, ``bounds`` and ``guess`` its own."""
    ratio, st, _ = least_peak_ratio(sp, p=p, bounds=bounds, tf_bounds=problem.tf_bounds_s,
                                 guess=guess, should_stop=should_stop)
    sol.stages.append({"stage": "least peak heating", "status": st.solver_status, "iterations": st.iterations,
                       "solve_time_s": st.solve_time_s})
    if ratio is None:
        return
    limit = problem.max_heat_rate_w_m2
    sol.status.details["least_peak_heat_rate_w_m2"] = ratio * limit
    if ratio > 1.0 + (problem.limit_tolerance or 0.0):
        sol.status.outcome = Outcome.INFEASIBLE
        sol.status.message = (f"infeasible: the least peak heating rate any control gives (a min-max solve at "
                              f"every RK4 step point) is {ratio * limit:.6g} W/m^2, above the limit {limit:.6g} "
                              f"({100 * (ratio - 1):+.1f}%); the limited NLP itself ended {sol.status.message}")


COARSE_INTERVALS = 20    # the certificate's first grid; the second has twice as many intervals
COARSE_SUBSTEPS = 4      # RK4 steps per interval: 80, then 160 step points sample the peak


def coarse_least_peak(problem, guess, *, should_stop=None) -> dict | None:
    """The least peak heating on two coarse grids before the limited NLP (module docstring):
    ``{"grids": [...], "least_peak_ratio", "error_estimate_w_m2", "proves_infeasible", ...}``, or None when
    a min-max solve does not converge (then nothing is concluded).  ``guess``: the job's initial
    guess (an :class:`~solvers.reentry.guess.InitialGuess`).  Stops after the first grid when its
    least peak is under the limit: the second grid could only confirm that nothing is proved."""

    limit = problem.max_heat_rate_w_m2
    tol = problem.limit_tolerance or 0.0
    p = param_vector(problem)
    grids: list[dict] = []
    ratio, peak_guess = None, 2.0
    for m in (COARSE_INTERVALS, 2 * COARSE_INTERVALS):
        pr = dataclasses.replace(problem, intervals=m, substeps=COARSE_SUBSTEPS)
        if grids:
            # From the first grid's answer the adaptive barrier update restarts far from the boundary
            # (169 iterations seen); a small fixed barrier keeps the warm start (22), as the solver's
            # WARM_IPOPT does.
            pr = dataclasses.replace(pr, ipopt={"mu_strategy": "monotone", "mu_init": 1e-3, **problem.ipopt})
        ratio, st, r = least_peak_ratio(shooting_problem(pr), p=p, bounds=state_bounds(pr, m),
                                        tf_bounds=pr.tf_bounds_s, guess=on_grid(guess, m, pr.control),
                                        should_stop=should_stop, peak_guess=peak_guess)
        grids.append({"intervals": m, "substeps": COARSE_SUBSTEPS, "status": st.solver_status,
                      "iterations": st.iterations, "solve_time_s": st.solve_time_s,
                      "least_peak_heat_rate_w_m2": None if ratio is None else ratio * limit})
        if ratio is None or ratio <= 1.0 + tol:
            break
        # The second grid starts from the first's answer (its controls at the nodes, its peak).
        guess = InitialGuess(t=r.t, x=r.x[:-1], u=control_at(r.t, r.t, r.u, pr.control))
        peak_guess = ratio
    if ratio is None:
        return None
    values = [g["least_peak_heat_rate_w_m2"] / limit for g in grids]
    error = abs(values[-1] - values[0]) if len(values) == 2 else None
    proves = error is not None and values[-1] - error > 1.0 + tol
    return {"grids": grids, "limit_w_m2": float(limit), "least_peak_ratio": values[-1],
            "least_peak_heat_rate_w_m2": values[-1] * limit,
            "error_estimate_w_m2": None if error is None else error * limit,
            "limit_tolerance": tol, "proves_infeasible": bool(proves)}
