"""The ``ocp`` kind's one refinement story: every phase's grid refined until the answer holds on its re-flight.

The same loop (:func:`solvers.transcription.refine.refine`) for one phase and several: its mesh is
a tuple of meshes, one per phase; each round solves all phases as one NLP (:class:`solvers.ocp.solver.OcpSolve`),
warm-started from the previous round's phases, and each phase's mesh is planned from that phase's
own interval errors and path excesses (a phase already within the accuracy, its limits and final
values held, keeps its mesh).  The worst scaled state error over the phases is the round's error.
Two planners:

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
  segments), at most ``TERMINAL_ROUNDS`` times (every phase not yet at its cap).

Every round is a record of ``solver.refinement`` (round, intervals over all phases, max_error,
objective, iterations, time_s); the answer returned is the accepted round's, else the best round's, whose
verification describes its own grid.  Not reaching the accuracy fails the job as
``accuracy_not_reached`` with that answer stored, or, with ``accuracy_required: false``, ends with a
note.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from solvers.common import Outcome
from solvers.ocp.problem import OcpProblem, PhaseProblem
from solvers.ocp.terminal import TERMINAL_TOLERANCE, finer, grid_words
from solvers.ocp.verify import LIMIT_TOLERANCE
from solvers.transcription import refine as rf

MAX_INTERVALS = 1000       # a refined mesh never grows past the service's default interval limit
MAX_NODES = 12             # LGL nodes per interval (the request's transcription.nodes limit)


def mesh_of(problem: PhaseProblem) -> rf.Mesh:
    tr = problem.transcription
    nodes = None
    if tr.method == "lgl":
        nodes = tr.segment_nodes or (tr.nodes,) * tr.intervals
    if tr.boundaries is None:
        return rf.Mesh.uniform(tr.intervals, None if nodes is None else tr.nodes)
    return rf.Mesh(tuple(tr.boundaries), nodes)


def on_mesh(problem: PhaseProblem, mesh: rf.Mesh) -> PhaseProblem:
    """The phase on ``mesh`` (a uniform mesh keeps the plain transcription: the same cached NLP)."""
    tr = problem.transcription
    uniform = mesh.is_uniform() and (mesh.nodes is None or mesh.nodes[0] == tr.nodes)
    tr = replace(tr, intervals=mesh.intervals, boundaries=None if uniform else tuple(mesh.boundaries),
                 segment_nodes=None if uniform or mesh.nodes is None else tuple(mesh.nodes))
    return replace(problem, phase=replace(problem.phase, transcription=tr))

def on_meshes(problem: OcpProblem, meshes) -> OcpProblem:
    """``problem`` with each phase on its mesh."""
    return problem.on_phases([on_mesh(ph.problem, m) for ph, m in zip(problem.phases, meshes)])


class PhaseView:
    """One phase of a round as its planner reads it; its local errors re-flown on first use (an accepted
    round needs none)."""

    def __init__(self, report: dict, errors: dict):
        self.verification = report["verification"]
        self.interval_excess = errors["path"]
        self.max_error = _finite(self.verification.get("max_state_difference_scaled_overall"))
        self._local = errors["state"]

    @property
    def interval_error(self):
        if callable(self._local):
            self._local = self._local()
        return self._local


class Trial:
    """One solve of :meth:`solvers.ocp.solver.OcpSolve.on_grid` seen by the refinement loop."""

    def __init__(self, sol, problem: OcpProblem):
        self.sol, self.problem = sol, problem
        ver = sol.verification or {}
        self.converged = sol.status.outcome in (Outcome.OPTIMAL, Outcome.LIMIT_NOT_HELD, Outcome.TERMINAL_NOT_HELD) \
            and bool(ver.get("ok"))
        self.max_error = _finite(ver.get("max_state_difference_scaled_overall"))
        self.objective = sol.objective
        self.iterations = sol.status.iterations
        self.intervals = sum(ph.problem.transcription.intervals for ph in problem.phases)
        self._views: dict[int, PhaseView] = {}

    def phase(self, i: int) -> PhaseView:
        if i not in self._views:
            self._views[i] = PhaseView(self.sol.phases[i], self.sol.interval_errors[i])
        return self._views[i]


def _finite(err) -> float:
    return float(err) if err is not None and math.isfinite(err) else math.inf


def plan_phase(tr, mesh: rf.Mesh, view: PhaseView, history, accuracy: float) -> rf.Mesh | None:
    """The next mesh of one phase (transcription ``tr``) from its round ``view`` (module docstring);
    ``history``: ``[(mesh, view)]`` of this phase's rounds, the current one last."""
    e = np.asarray(view.interval_error if view.interval_error is not None else np.full(mesh.intervals, np.inf))
    e = np.where(np.isfinite(e), e, np.inf)
    if view.max_error <= accuracy and not view.verification.get("terminal_held", True):
        accuracy = min(accuracy, TERMINAL_TOLERANCE)
    target = rf.round_target(accuracy, view.max_error, e[np.isfinite(e)])
    force = []
    if view.interval_excess is not None and not view.verification.get("limits_held", True):
        force = [int(k) for k in np.flatnonzero(view.interval_excess > LIMIT_TOLERANCE)]
    if tr.method == "multiple_shooting":
        nxt = rf.split_shooting(mesh, e, target, force=force)
    else:
        previous = rf.lgl_history(history[-2][0], history[-2][1].interval_error) if len(history) > 1 else None
        if previous is not None:
            previous = {k: v for k, v in previous.items() if math.isfinite(v[1])}
        nxt = rf.refine_lgl(mesh, e, target, n_min=tr.nodes, n_max=MAX_NODES, previous=previous, force=force)
    if nxt is None and view.max_error > accuracy:
        # every interval within its share, yet the total misses: halve the worst quarter
        worst = np.argsort(e)[-max(1, mesh.intervals // 4):]
        nxt = (rf.split_shooting(mesh, np.zeros_like(e), target, force=list(worst)) if tr.method != "lgl"
               else rf.refine_lgl(mesh, np.zeros_like(e), target, n_min=tr.nodes, n_max=MAX_NODES,
                                  force=list(worst)))
    if nxt is None or nxt.intervals > MAX_INTERVALS:
        return None
    return nxt


class Refinement:
    """The refinement rounds of one :class:`solvers.ocp.solver.OcpSolve` (module docstring)."""

    def __init__(self, solve):
        self.solve, self.problem = solve, solve.problem
        self.trials: list[Trial] = []

    def _round(self, problem: OcpProblem, previous, on_progress) -> Trial:
        warm = previous.sol.warm() if isinstance(previous, Trial) else previous
        self.trials.append(Trial(self.solve.on_grid(problem, warm, on_progress), problem))
        return self.trials[-1]

    def to_accuracy(self):
        """The loop with the accuracy planner; returns the solution to report (module docstring)."""
        problem, accuracy, progress = self.problem, self.problem.accuracy, self.solve.on_progress

        def solve(meshes, previous):
            intervals = sum(m.intervals for m in meshes)
            return self._round(on_meshes(problem, meshes), previous,
                               round_progress(progress, len(self.trials), intervals))

        def accept(trial: Trial) -> bool:
            return trial.sol.status.outcome is Outcome.OPTIMAL and trial.max_error <= accuracy

        def plan(meshes, trial: Trial, history):
            out, changed = [], False
            for i, (ph, mesh) in enumerate(zip(trial.problem.phases, meshes)):
                view = trial.phase(i)
                held = view.verification.get("limits_held", True) and view.verification.get("terminal_held", True)
                nxt = None
                if not (view.max_error <= accuracy and held):
                    nxt = plan_phase(ph.problem.transcription, mesh, view,
                                     [(m[i], t.phase(i)) for m, t in history], accuracy)
                out.append(mesh if nxt is None else nxt)
                changed |= nxt is not None
            return tuple(out) if changed else None

        max_rounds = max(ph.problem.transcription.max_refinements for ph in problem.phases)
        out = rf.refine(mesh=tuple(mesh_of(ph.problem) for ph in problem.phases), solve=solve, accept=accept,
                        plan=plan, max_rounds=max_rounds, should_stop=self.solve.should_stop,
                        previous=self.solve.initial_guess)
        if out.last.sol.status.outcome is Outcome.CANCELLED:
            out.best = out.last          # a cancelled job says so, whatever an earlier round reached
        elif out.stopped == "cancelled":         # asked to stop between two rounds
            out.best.sol.status.outcome = Outcome.CANCELLED
            out.best.sol.status.message = "cancelled between mesh-refinement rounds"
        sol = self._account(out)
        sol.solver.update(refinement=out.rounds, accuracy=accuracy, accuracy_reached=out.reached)
        summary = (rounds_summary("mesh", accuracy, out.rounds) if problem.single
                   else rounds_summary("every phase's mesh", accuracy, out.rounds) + " over all phases")
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
            sol.status.message = (f"the re-flown states depart from the answer by {err_words(out.best.max_error)} "
                                  f"(scaled), more than the accuracy {accuracy:g}, after {len(out.rounds) - 1} "
                                  f"refinement round(s) ({why}; transcription.max_refinements {max_rounds}); the "
                                  "best round is stored; accuracy_required: false accepts it with a note")
            sol.status.details["refinement"] = out.rounds
            sol.solver.update(outcome=sol.status.outcome.value, message=sol.status.message)
        return sol

    def terminal(self, rounds: int):
        """The loop without ``accuracy``: every phase's grid refined uniformly while a final value is missed."""
        problem, words = self.problem, []

        def solve(p, previous):
            return self._round(p, previous, self.solve.on_progress)

        def plan(p: OcpProblem, trial, history):
            finer_phases = [finer(ph.problem) or ph.problem for ph in p.phases]
            changed = [(ph, q) for ph, q in zip(p.phases, finer_phases) if q is not ph.problem]
            if not changed:
                return None
            words.append(", ".join(f"{ph.name + ': ' if ph.name else ''}{grid_words(ph.problem)} -> {grid_words(q)}"
                                   for ph, q in changed))
            return p.on_phases(finer_phases)

        def accept(trial):
            return trial.sol.status.outcome is not Outcome.TERMINAL_NOT_HELD

        out = rf.refine(mesh=problem, solve=solve, accept=accept, plan=plan, max_rounds=rounds,
                        should_stop=self.solve.should_stop, previous=self.solve.initial_guess)
        out.best = out.last      # the last round is the answer here: a terminal miss refined is kept either way
        sol = self._account(out)
        if words:
            held = sol.verification.get("terminal_held")
            sol.notes.insert(0, "terminal conditions missed on the re-flight, grid refined (warm-started): "
                             + "; ".join(words) + f"; now {'held' if held else 'NOT held'}")
            sol.solver["terminal_refinements"] = words
            sol.solver["refinement"] = out.rounds
        return sol

    def _account(self, out: rf.RefineResult):
        """The answer with the work of every round counted in its status and ``solver``."""
        sol = out.best.sol
        if len(self.trials) > 1:
            st = sol.status
            st.iterations = sum(t.sol.status.iterations for t in self.trials)
            st.solve_time_s = sum(t.sol.status.solve_time_s for t in self.trials)
            st.build_time_s = sum(t.sol.status.build_time_s for t in self.trials)
            sol.solver.update(iterations=st.iterations, solve_time_s=st.solve_time_s, build_time_s=st.build_time_s)
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
