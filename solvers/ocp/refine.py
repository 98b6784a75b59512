"""The ``ocp`` kind's one refinement story: a grid refined until the answer holds on its re-flight.

Two planners drive the same loop (:func:`solvers.transcription.refine.refine`):

* with ``accuracy`` (``shared/specs/ocp.md``, "Mesh refinement"): each round re-flies every interval
  from its own first node (:func:`solvers.ocp.verify.verify` with ``local=True``), splits the
  multiple-shooting intervals that miss their share of the accuracy or raises the degree of / splits
  the LGL intervals (:mod:`solvers.transcription.refine`), splits the intervals where a path limit
  is still exceeded after the tightening rounds, and solves again warm-started from the previous
  answer interpolated onto the new mesh; until the re-flown states agree with the answer to
  ``accuracy`` (each state scaled by its ``scale``), every path limit holds on the dense grid and
  every terminal value holds, at most ``transcription.max_refinements`` rounds.  A fixed final value
  missed while the accuracy is met lowers that round's target to the terminal tolerance.
* without ``accuracy`` the grid is the one given; only a final value missed on the re-flight
  (:mod:`solvers.ocp.terminal`) refines it uniformly (twice the RK4 steps or twice the LGL
  segments), at most ``TERMINAL_ROUNDS`` times, as before.

Every round is a record of ``solver.refinement`` (round, intervals, max_error, objective,
iterations, time_s); the answer returned is the accepted round's, else the best round's, whose
verification describes its own grid.  Not reaching the accuracy fails the job as
``accuracy_not_reached`` with that answer stored, or, with ``accuracy_required: false``, ends with a
note.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from solvers.common import Outcome
from solvers.ocp.terminal import TERMINAL_TOLERANCE, finer, grid_words
from solvers.ocp.verify import LIMIT_TOLERANCE
from solvers.transcription import refine as rf

MAX_INTERVALS = 1000       # a refined mesh never grows past the service's default interval limit
MAX_NODES = 12             # LGL nodes per interval (the request's transcription.nodes limit)


class Trial:
    """One solve of :func:`solvers.ocp.solver._solve_on_grid` seen by the refinement loop."""

    def __init__(self, sol, problem, seconds: float = 0.0):
        self.sol, self.problem = sol, problem
        ver = sol.verification or {}
        self.converged = sol.status.outcome in (Outcome.OPTIMAL, Outcome.LIMIT_NOT_HELD, Outcome.TERMINAL_NOT_HELD) \
            and bool(ver.get("ok"))
        err = ver.get("max_state_difference_scaled_overall")
        self.max_error = float(err) if err is not None and math.isfinite(err) else math.inf
        self.objective = sol.objective
        self.iterations = sol.status.iterations
        self.intervals = problem.transcription.intervals
        self._local = sol.interval_errors.get("state")
        self.interval_excess = sol.interval_errors.get("path")

    @property
    def interval_error(self):
        """The scaled local error per interval, re-flown on first use (an accepted round needs none)."""
        if callable(self._local):
            self._local = self._local()
        return self._local


def mesh_of(problem) -> rf.Mesh:
    tr = problem.transcription
    nodes = None
    if tr.method == "lgl":
        nodes = tr.segment_nodes or (tr.nodes,) * tr.intervals
    if tr.boundaries is None:
        return rf.Mesh.uniform(tr.intervals, None if nodes is None else tr.nodes)
    return rf.Mesh(tuple(tr.boundaries), nodes)


def on_mesh(problem, mesh: rf.Mesh):
    """``problem`` on ``mesh`` (a uniform mesh keeps the plain transcription: the same cached NLP)."""
    tr = problem.transcription
    uniform = mesh.is_uniform() and (mesh.nodes is None or mesh.nodes[0] == tr.nodes)
    tr = replace(tr, intervals=mesh.intervals, boundaries=None if uniform else tuple(mesh.boundaries),
                 segment_nodes=None if uniform or mesh.nodes is None else tuple(mesh.nodes))
    return replace(problem, phase=replace(problem.phase, transcription=tr))


def warm_of(sol) -> dict:
    return {"trajectory": sol.trajectory, "tf": sol.tf, "parameters": sol.parameters}


def accepts(problem):
    def accept(trial: Trial) -> bool:
        return trial.sol.status.outcome is Outcome.OPTIMAL and trial.max_error <= problem.accuracy
    return accept


def planner(problem):
    """``plan(mesh, trial, history) -> mesh | None`` for ``problem`` (module docstring)."""
    tr = problem.transcription

    def plan(mesh: rf.Mesh, trial: Trial, history) -> rf.Mesh | None:
        e = np.asarray(trial.interval_error if trial.interval_error is not None else np.full(mesh.intervals, np.inf))
        e = np.where(np.isfinite(e), e, np.inf)
        accuracy = problem.accuracy
        if trial.max_error <= accuracy and not trial.sol.verification.get("terminal_held", True):
            accuracy = min(accuracy, TERMINAL_TOLERANCE)
        target = rf.round_target(accuracy, trial.max_error, e[np.isfinite(e)])
        force = []
        if trial.interval_excess is not None and not trial.sol.verification.get("limits_held", True):
            force = [int(k) for k in np.flatnonzero(trial.interval_excess > LIMIT_TOLERANCE)]
        if tr.method == "multiple_shooting":
            nxt = rf.split_shooting(mesh, e, target, force=force)
        else:
            previous = rf.lgl_history(history[-2][0], history[-2][1].interval_error) if len(history) > 1 else None
            if previous is not None:
                previous = {k: v for k, v in previous.items() if math.isfinite(v[1])}
            nxt = rf.refine_lgl(mesh, e, target, n_min=tr.nodes, n_max=MAX_NODES, previous=previous,
                                force=force)
        if nxt is None and trial.max_error > accuracy:
            # every interval within its share, yet the total misses: halve the worst quarter
            worst = np.argsort(e)[-max(1, mesh.intervals // 4):]
            nxt = (rf.split_shooting(mesh, np.zeros_like(e), target, force=list(worst)) if tr.method != "lgl"
                   else rf.refine_lgl(mesh, np.zeros_like(e), target, n_min=tr.nodes, n_max=MAX_NODES,
                                      force=list(worst)))
        if nxt is None or nxt.intervals > MAX_INTERVALS:
            return None
        return nxt
    return plan


def solve_refined(problem, *, solve_on_grid, initial_guess, should_stop, **kw):
    """The loop with the accuracy planner; returns the solution to report (module docstring)."""

    trials: list[Trial] = []

    progress = kw.pop("on_progress", None)

    def solve(mesh, previous):
        p = on_mesh(problem, mesh)
        warm = previous if not isinstance(previous, Trial) else warm_of(previous.sol)
        trials.append(Trial(solve_on_grid(p, initial_guess=warm, should_stop=should_stop,
                                          on_progress=round_progress(progress, len(trials), mesh.intervals), **kw), p))
        return trials[-1]

    out = rf.refine(mesh=mesh_of(problem), solve=solve, accept=accepts(problem), plan=planner(problem),
                    max_rounds=problem.transcription.max_refinements, should_stop=should_stop,
                    previous=initial_guess)
    if out.last.sol.status.outcome is Outcome.CANCELLED:
        out.best = out.last          # a cancelled job says so, whatever an earlier round reached
    elif out.stopped == "cancelled":         # asked to stop between two rounds
        out.best.sol.status.outcome = Outcome.CANCELLED
        out.best.sol.status.message = "cancelled between mesh-refinement rounds"
    sol = _account(out, trials)
    sol.solver["refinement"] = out.rounds
    best = out.best
    sol.solver["accuracy"] = problem.accuracy
    sol.solver["accuracy_reached"] = out.reached
    summary = rounds_summary("mesh", problem.accuracy, out.rounds)
    if out.reached:
        sol.notes.insert(0, summary + "; reached")
        return sol
    why = out.stopped or "not reached"
    sol.notes.insert(0, summary + f"; NOT reached ({why}); the answer is round {_round_of(out)}'s")
    # a final value missed is the accuracy missed (the refinement owns it); a limit not held stays so
    if sol.status.outcome in (Outcome.OPTIMAL, Outcome.TERMINAL_NOT_HELD) and problem.accuracy_required:
        if sol.status.outcome is Outcome.TERMINAL_NOT_HELD:
            sol.notes.append("terminal: " + sol.status.message)
        sol.status.outcome = Outcome.ACCURACY_NOT_REACHED
        sol.status.message = (f"the re-flown states depart from the answer by {err_words(best.max_error)} (scaled), "
                              f"more than the accuracy {problem.accuracy:g}, after {len(out.rounds) - 1} "
                              f"refinement round(s) ({why}; transcription.max_refinements "
                              f"{problem.transcription.max_refinements}); the best round is stored; "
                              "accuracy_required: false accepts it with a note")
        sol.status.details["refinement"] = out.rounds
    return sol


def solve_terminal(problem, *, solve_on_grid, initial_guess, should_stop, rounds: int, **kw):
    """The loop without ``accuracy``: uniform refinement while a final value is missed."""
    words: list[str] = []
    trials: list[Trial] = []

    def solve(p, previous):
        warm = previous if not isinstance(previous, Trial) else warm_of(previous.sol)
        trials.append(Trial(solve_on_grid(p, initial_guess=warm, should_stop=should_stop, **kw), p))
        return trials[-1]

    def plan(p, trial, history):
        nxt = finer(p)
        if nxt is not None:
            words.append(f"{grid_words(p)} -> {grid_words(nxt)}")
        return nxt

    def accept(trial):
        return trial.sol.status.outcome is not Outcome.TERMINAL_NOT_HELD

    out = rf.refine(mesh=problem, solve=solve, accept=accept, plan=plan, max_rounds=rounds,
                    should_stop=should_stop, previous=initial_guess)
    # the last round is the answer here (as before): a terminal miss refined is kept either way
    out.best = out.last
    sol = _account(out, trials)
    if words:
        held = sol.verification.get("terminal_held")
        sol.notes.insert(0, "terminal conditions missed on the re-flight, grid refined (warm-started): "
                         + "; ".join(words) + f"; now {'held' if held else 'NOT held'}")
        sol.solver["terminal_refinements"] = words
        sol.solver["refinement"] = out.rounds
    return sol


def round_progress(progress, k: int, intervals: int):
    """The job's progress for round ``k``: round 0 fills [0, 1/2], round 1 [1/2, 3/4], ... (the
    number of rounds is not known ahead), each message prefixed with its round."""
    if progress is None:
        return None
    lo = 1.0 - 0.5**k

    def on_progress(fraction: float, message: str) -> None:
        progress(lo + 0.5**(k + 1) * fraction, f"refinement round {k} ({intervals} intervals): {message}")
    return on_progress


def _account(out: rf.RefineResult, trials: list[Trial]):
    """The answer with the work of every round counted in its status and ``solver``."""
    sol = out.best.sol
    if len(trials) > 1:
        st = sol.status
        st.iterations = sum(t.sol.status.iterations for t in trials)
        st.solve_time_s = sum(t.sol.status.solve_time_s for t in trials)
        st.build_time_s = sum(t.sol.status.build_time_s for t in trials)
        sol.solver.update(iterations=st.iterations, solve_time_s=st.solve_time_s, build_time_s=st.build_time_s)
    return sol


def _round_of(out) -> int:
    for r in out.rounds:
        if r["intervals"] == out.best.intervals and r["objective"] == out.best.objective:
            return r["round"]
    return out.rounds[-1]["round"]


def rounds_summary(what: str, accuracy: float, rounds: list[dict]) -> str:
    """The note that opens a refined answer: each round's intervals and worst scaled state error."""
    return (f"{what} refined to the accuracy {accuracy:g}: "
            + " -> ".join(f"{r['intervals']} ({err_words(r['max_error'])})" for r in rounds)
            + " intervals (worst scaled state error)")


def err_words(v) -> str:
    return "n/a" if v is None or not math.isfinite(v) else f"{v:.2g}"
