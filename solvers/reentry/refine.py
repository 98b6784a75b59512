"""The ``reentry`` kind's grid refined to a stated accuracy (issue 26): ``accuracy`` replaces guessing
``grid.intervals``.

:func:`solve` is the package's ``solve``: without ``problem.accuracy`` it is
:func:`solvers.reentry.solver.solve` unchanged; with it, the loop of
:mod:`solvers.transcription.refine` runs on the number of shooting intervals (the reentry
transcription keeps equal intervals, so a round refines them all alike):

1. solve on ``problem.intervals`` (limits held as always; a terminal value missed is not refined by
   more substeps, as without ``accuracy``, but by this loop: the round is not accepted);
2. re-fly every interval from its own node with 40 RK4 steps (what the verification uses, 20x the
   NLP's step) and compare with the next node: the local error of each interval, scaled by each
   state's scale (:data:`solvers.models.reentry_state.X_SCALE`); the global error is the
   verification's continuous re-propagation against the nodes, scaled alike;
3. when the global error is above ``accuracy``, take the interval count whose local errors sum to
   the target (:func:`solvers.transcription.refine.uniform_count`, RK4's order 4) and solve again,
   warm-started from the answer;
4. at most ``max_refinements`` rounds; short of the accuracy the solve ends ``accuracy_not_reached``
   with the best round (or, ``accuracy_required`` false, succeeds with a note).

The rounds are ``status.details["refinement"]`` (round, intervals, max_error, objective,
iterations, time_s); every round's IPOPT stages are kept, prefixed with their round.
"""
from __future__ import annotations

import dataclasses
import math
import threading

import casadi as ca
import numpy as np

from solvers.common import Outcome
from solvers.models.reentry_state import NU, NX, X_SCALE
from solvers.reentry.shooting import param_vector, shooting_problem
from solvers.reentry.stages import GRID_PLAN, PLAN
from solvers.progress import Progress
from solvers.transcription import refine as rf

MAX_INTERVALS = 1000        # the service's default max_grid_intervals
LOCAL_STEPS = 40            # RK4 steps per interval of the local re-flight (the verification's 2 x 20)
_CACHE: dict = {}
_LOCK = threading.Lock()


class Trial:
    def __init__(self, sol, problem):
        self.sol, self.problem = sol, problem
        self.intervals = problem.intervals
        self.objective = sol.objective_value
        self.iterations = sol.status.iterations
        ver = sol.verification
        self.converged = sol.status.outcome in (Outcome.OPTIMAL, Outcome.LIMIT_NOT_HELD,
                                                Outcome.TERMINAL_NOT_HELD) and ver is not None and ver.ok
        self.max_error = float(np.max(ver.max_node_difference / np.asarray(X_SCALE))) if self.converged else math.inf
        self.interval_error = local_errors(problem, sol) if self.converged else None


def _local_fn(problem, intervals: int) -> ca.Function:

    sp = shooting_problem(problem)
    key = (sp.key, problem.control, intervals, len(param_vector(problem)))
    with _LOCK:
        if key in _CACHE:
            return _CACHE[key]
    x, ua, ub = ca.SX.sym("x", NX), ca.SX.sym("ua", NU), ca.SX.sym("ub", NU)
    dt, p = ca.SX.sym("dt"), ca.SX.sym("p", sp.n_params)
    linear = problem.control == "linear"

    def u(f):
        return ua + f * (ub - ua) if linear else ua

    y, h = x, dt / LOCAL_STEPS
    for j in range(LOCAL_STEPS):
        f0, f1 = j / LOCAL_STEPS, (j + 1) / LOCAL_STEPS
        k1 = sp.dynamics(y, u(f0), p)
        k2 = sp.dynamics(y + 0.5 * h * k1, u(0.5 * (f0 + f1)), p)
        k3 = sp.dynamics(y + 0.5 * h * k2, u(0.5 * (f0 + f1)), p)
        k4 = sp.dynamics(y + h * k3, u(f1), p)
        y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    fn = ca.Function("reentry_local", [x, ua, ub, dt, p], [y]).map(intervals)
    with _LOCK:
        if len(_CACHE) > 8:
            _CACHE.clear()
        _CACHE[key] = fn
    return fn


def local_errors(problem, sol) -> np.ndarray:
    """Per interval: the worst scaled difference between the next node and the interval re-flown
    from its own node (module docstring)."""

    m = problem.intervals
    x, u = np.asarray(sol.x, float), np.asarray(sol.u, float)
    ua = u[:, :m]
    ub = u[:, 1:m + 1] if problem.control == "linear" else ua
    dt = np.diff(np.asarray(sol.t, float))[None, :]
    p = np.tile(param_vector(problem)[:, None], (1, m))
    ends = np.asarray(_local_fn(problem, m)(x[:, :m], ua, ub, dt, p))
    return np.max(np.abs(ends - x[:, 1:]) / np.asarray(X_SCALE)[:, None], axis=0)


def solve(problem, *, initial_guess=None, on_progress=None, should_stop=None, seed=None):
    """:func:`solvers.reentry.solver.solve`, refined to ``problem.accuracy`` when it is set."""
    from solvers.reentry import solver as base
    from solvers.reentry.guess import InitialGuess

    if problem.accuracy is None:
        return base.solve(problem, initial_guess=initial_guess, seed=seed, on_progress=on_progress,
                          should_stop=should_stop)
    progress = Progress(on_progress, PLAN)
    trials: list[Trial] = []

    def solve_on(m, previous):
        # terminal_rounds 0: a final value missed is refined here, by intervals, not by substeps
        p = dataclasses.replace(problem, intervals=int(m), terminal_rounds=0)
        guess = initial_guess if not isinstance(previous, Trial) else InitialGuess(
            t=previous.sol.t, x=previous.sol.x, u=previous.sol.u_nodes_at_t)
        # round 0 (the grid as given) on the job's own stages, round k inside refinement round k's share
        k = len(trials)
        stages = progress.within("refinement", GRID_PLAN, round=k) if k else progress
        trials.append(Trial(base.solve(p, initial_guess=guess, on_progress=stages, should_stop=should_stop), p))
        return trials[-1]

    def accept(trial):
        return trial.sol.status.outcome is Outcome.OPTIMAL and trial.max_error <= problem.accuracy

    def plan(m, trial, history):
        e = trial.interval_error
        target = rf.round_target(problem.accuracy, trial.max_error, e)
        if trial.max_error <= problem.accuracy:        # accurate, yet a final value or a limit missed
            target = min(target, 0.25 * float(np.sum(e)))
        return rf.uniform_count(m, e, target, max_intervals=MAX_INTERVALS)

    out = rf.refine(mesh=problem.intervals, solve=solve_on, accept=accept, plan=plan,
                    max_rounds=problem.max_refinements, should_stop=should_stop, previous=initial_guess)
    if out.last.sol.status.outcome is Outcome.CANCELLED:
        out.best = out.last          # a cancelled job says so, whatever an earlier round reached
    elif out.stopped == "cancelled":         # asked to stop between two rounds
        out.best.sol.status.outcome = Outcome.CANCELLED
        out.best.sol.status.message = "cancelled between mesh-refinement rounds"
    progress.stage("answer")
    sol = _report(problem, out, trials)
    progress.done(sol.status.outcome.value)
    return sol


def _report(problem, out, trials):
    sol = out.best.sol
    st = sol.status
    if len(trials) > 1:
        stages = []
        for k, t in enumerate(trials):
            stages += [{**s, "stage": f"round {k} ({t.intervals} intervals): {s['stage']}"} for s in t.sol.stages]
        sol.stages[:] = stages
        st.iterations = sum(t.sol.status.iterations for t in trials)
        st.solve_time_s = sum(t.sol.status.solve_time_s for t in trials)
        st.build_time_s = sum(t.sol.status.build_time_s for t in trials)
        st.details["stages"] = stages
    st.details["refinement"] = out.rounds
    st.details["accuracy"] = problem.accuracy
    st.details["accuracy_reached"] = out.reached
    path = " -> ".join(f"{r['intervals']} ({'n/a' if r['max_error'] is None else format(r['max_error'], '.2g')})"
                       for r in out.rounds)
    if out.reached:
        sol.notes.insert(0, f"grid refined to the accuracy {problem.accuracy:g}: {path} intervals "
                            "(worst scaled state error of the re-propagation); reached")
        return sol
    why = out.stopped or "not reached"
    sol.notes.insert(0, f"grid refined to the accuracy {problem.accuracy:g}: {path} intervals; NOT reached ({why}); "
                        f"the answer is the best round's ({out.best.intervals} intervals)")
    # a final value missed is the accuracy missed (the refinement owns it); a limit not held stays so
    if st.outcome in (Outcome.OPTIMAL, Outcome.TERMINAL_NOT_HELD) and problem.accuracy_required:
        if st.outcome is Outcome.TERMINAL_NOT_HELD:
            sol.notes.append("terminal: " + st.message)
        st.outcome = Outcome.ACCURACY_NOT_REACHED
        st.message = (f"the re-propagated states depart from the answer by {out.best.max_error:.3g} (scaled), more "
                      f"than the accuracy {problem.accuracy:g}, after {len(out.rounds) - 1} refinement round(s) "
                      f"({why}; grid.max_refinements {problem.max_refinements}); the best round is stored; "
                      "accuracy_required: false accepts it with a note")
    return sol
