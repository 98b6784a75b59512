"""Infeasibility proved, not guessed: a path limit that no control can keep at a pinned end.

The entry state is fixed, and so are the final altitude and speed when the terminal conditions name
both.  The heating rate and the dynamic pressure depend on the state only through altitude and speed
(and, for Betts' heating fit, on the angle of attack): at a pinned end the least value any admissible
control can give is a number, computed exactly here (Sutton-Graves and the dynamic pressure do not
depend on the control; Betts' fit is a cubic in alpha, minimized over the alpha bounds at the bounds
and the cubic's stationary points).  When that least value exceeds the limit by more than the
limit's tolerance, no trajectory keeps the limit: the problem is infeasible, proved before any
NLP iteration and independent of the CPU's iterates.  (An aero-table shuttle with Sutton-Graves
heating and a 2e5 W/m^2 limit starts at 3.77e5 W/m^2: it failed as ``not_converged`` after 1,000
IPOPT iterations and 69.5 s before, issue 25.)

A limit that both ends keep but the flight between cannot is not caught here; that needs the least
peak any control can give along the way (a min-max solve), which this module does not attempt.
"""
from __future__ import annotations

import numpy as np

from solvers.common import Outcome, SolveStatus
from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.models.reentry_state import ALTITUDE, SPEED
from solvers.reentry.guess import on_grid
from solvers.reentry.problem import ReentryProblem, ReentrySolution
from solvers.transcription.multiple_shooting import control_at


def _alpha_candidates(problem: ReentryProblem) -> np.ndarray:
    """Where the least heating over the alpha bounds can be: the bounds, and for Betts' cubic fit
    its stationary points inside them."""
    lo, hi = problem.alpha_bounds_rad
    cands = [lo, hi]
    if problem.vehicle.heating is None:
        der = np.polynomial.polynomial.polyder(np.asarray(problem.vehicle.heat_coeffs, float))
        for r in np.polynomial.polynomial.polyroots(der):
            if abs(r.imag) < 1e-12 and lo <= r.real * sh.DEG <= hi:
                cands.append(r.real * sh.DEG)
    return np.asarray(cands, float)


def pinned_ends(problem: ReentryProblem) -> dict[str, np.ndarray]:
    """The ends whose altitude and speed are fixed: the entry always, the end when both are pinned."""
    ends = {"entry": np.asarray(problem.initial_state, float)}
    t = problem.terminal
    if t.altitude_m is not None and t.speed_mps is not None:
        xf = ends["entry"].copy()
        xf[ALTITUDE], xf[SPEED] = t.altitude_m, t.speed_mps
        ends["end"] = xf
    return ends


def least_at_pinned_ends(problem: ReentryProblem) -> list[dict]:
    """Per limited quantity (heating, dynamic pressure) and pinned end, the least value any
    admissible control gives there, with the limit and whether it is beyond the limit's tolerance."""
    alphas = _alpha_candidates(problem)
    tol = problem.limit_tolerance or 0.0
    out = []
    for where, x in pinned_ends(problem).items():
        X = np.tile(x[:, None], (1, alphas.size))
        U = np.vstack([alphas, np.zeros(alphas.size)])
        for quantity, limit, values in (
                ("heat_rate_w_m2", problem.max_heat_rate_w_m2, lambda X=X, U=U: dyn.heat_rate(X, U, problem.vehicle, np)),
                ("dynamic_pressure_pa", problem.max_dynamic_pressure_pa,
                 lambda X=X: dyn.dynamic_pressure(X, problem.vehicle, np))):
            if limit is None:
                continue
            least = float(np.min(values()))
            out.append({"quantity": quantity, "where": where, "least": least, "limit": float(limit),
                        "proves_infeasible": bool(least > limit * (1.0 + tol))})
    return out


def certified_infeasible(problem: ReentryProblem, guess) -> ReentrySolution | None:
    """An ``infeasible`` solution (no NLP solved) when a pinned end proves a limit cannot hold, else None.
    The arrays are the initial guess on the grid, kept only so that the stored result has a shape."""
    bounds = least_at_pinned_ends(problem)
    proofs = [b for b in bounds if b["proves_infeasible"]]
    if not proofs:
        return None
    worst = max(proofs, key=lambda b: b["least"] / b["limit"])
    msg = "; ".join(f"at the {b['where']} (its altitude and speed are fixed) no admissible control gives "
                    f"{b['quantity']} below {b['least']:.6g}, against the limit {b['limit']:.6g} "
                    f"({100 * (b['least'] / b['limit'] - 1):+.1f}%)" for b in proofs)
    return infeasible_before_the_nlp(problem, guess, solver_status="pinned_end_bound",
                                     message=f"infeasible, proved before the NLP: {msg}",
                                     violation=worst["least"] / worst["limit"] - 1.0,
                                     details={"certificate": bounds}, note=f"no NLP was solved: {msg}")


def infeasible_before_the_nlp(problem: ReentryProblem, guess, *, solver_status: str, message: str,
                              violation: float, details: dict, note: str,
                              stages: list | None = None) -> ReentrySolution:
    """The ``infeasible`` solution of a problem shown infeasible before the limited NLP ran: the
    evidence in ``details``, the arrays the initial guess on the grid (a stored result has a shape)."""
    m = problem.intervals
    tf, x, u = on_grid(guess, m, problem.control)
    t = np.linspace(0.0, tf, m + 1)
    u_nodes = control_at(t, t, u, problem.control)
    stages = list(stages or [])
    status = SolveStatus(Outcome.INFEASIBLE, solver_status=solver_status, message=message,
                         iterations=sum(s.get("iterations", 0) for s in stages),
                         solve_time_s=sum(s.get("solve_time_s", 0.0) for s in stages),
                         max_constraint_violation=violation, details={**details, "stages": stages})
    return ReentrySolution(status=status, objective_name=problem.objective, objective_value=float("nan"),
                           objective_unit="rad", tf_s=float(tf), t=t, x=x, u=u, u_nodes_at_t=u_nodes,
                           heat_rate=np.asarray(dyn.heat_rate(x, u_nodes, problem.vehicle, np), float),
                           verification=None,
                           notes=[f"{note}; the trajectory is the initial guess, not an answer"],
                           stages=stages)
