"""The ``ocp`` kind's one refinement story: every phase's grid refined until the answer holds on its re-flight.

The same loop (:func:`solvers.transcription.refine.refine`) for one phase and several: its mesh is
a tuple of meshes, one per phase; each round solves all phases as one NLP (:class:`solvers.ocp.solver.OcpSolve`),
warm-started from the previous round's phases, and each phase's mesh is planned from that phase's
own interval errors and path excesses (a phase already within the accuracy, its limits and final
values held, keeps its mesh).  The worst scaled state error over the phases is the round's error.
Two planners:

* with ``accuracy`` (``shared/specs/ocp.md``, "Mesh refinement": the accuracy of the *answer*, its states
  and its objective against the continuous optimum): each round solves on its mesh and checks the answer
  against a solve on the nested finer mesh (:mod:`solvers.ocp.estimate`: every interval cut in two or
  three, warm-started), which estimates the objective's relative error and the states' scaled error and
  shares them among the intervals (where the controls move when the mesh is refined: a switch or a kink
  inside an interval); the next mesh splits the intervals that hold more than their share (multiple
  shooting) or raises their degree / splits them (LGL), together with the intervals whose own re-flight
  from their first node misses (:func:`solvers.ocp.verify.local_errors`,
  :mod:`solvers.transcription.refine`) and those where a path limit is still exceeded after the
  tightening rounds; solved again warm-started from the check's answer (a next mesh that is the check's
  is the check's solve, not solved twice); until both estimates are within ``accuracy``, every path limit
  holds on the dense grid and every terminal value holds, at most ``transcription.max_refinements``
  rounds.  A fixed final value missed while the accuracy is met lowers that round's target to the
  terminal tolerance.
* without ``accuracy`` the grid is the one given; only a final value missed on the re-flight
  (:mod:`solvers.ocp.terminal`) refines it uniformly (twice the RK4 steps or twice the LGL
  segments), at most ``TERMINAL_ROUNDS`` times (every phase not yet at its cap).

Either way the answer carries ``solver.accuracy`` (requested, state_error, objective_error_estimate,
reached, how they were estimated and the check's numbers); without ``accuracy`` the answer is checked
once, after the loop.  Every round is a record of ``solver.refinement`` (round, intervals over all
phases, max_error: the re-flight's, state_error, objective, objective_error_estimate, the check's
intervals, objective and iterations, iterations, time_s); the answer returned is the accepted round's, else the best round's, whose
verification describes its own grid.  Not reaching the accuracy fails the job as
``accuracy_not_reached`` with that answer stored, or, with ``accuracy_required: false``, ends with a
note.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from solvers.common import Outcome
from solvers.ocp.estimate import METHOD as ESTIMATE_METHOD
from solvers.ocp.estimate import Estimate, accuracy_block, estimate, halved, parts_of, plan_estimate, same_mesh, union
from solvers.ocp.problem import OcpProblem, PhaseProblem
from solvers.ocp.stages import CHECK_PLAN, GRID_PLAN
from solvers.progress import Progress
from solvers.ocp.terminal import TERMINAL_TOLERANCE, finer, grid_words
from solvers.ocp.verify import LIMIT_TOLERANCE
from solvers.transcription import refine as rf

MAX_INTERVALS = 1000       # a refined mesh never grows past the service's default interval limit
MAX_NODES = 12             # LGL nodes per interval (the request's transcription.nodes limit)
# The check starts from the answer, but a bang-bang answer interpolated onto a finer mesh is no longer at
# the bounds where it should be: IPOPT's own defaults take it there in fewer iterations than the small
# barrier of a warm start (lunar lander 60 -> 120 intervals: 12 iterations instead of 44).
CHECK_IPOPT: dict = {}
STALL = 0.5                # a round that does not cut the error to this fraction of the best is no progress
STALL_GROWTH = 4           # refined everywhere after a stall up to this many times the first round's intervals
STALL_FLOOR = 200          # (or this many)
CHECK_REUSE = 0.6          # a plan with this share of the check mesh's intervals takes the check mesh


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
        self.estimate: Estimate | None = None      # against the check on the finer mesh (solvers.ocp.estimate)
        self.fine: Trial | None = None             # that check's own solve
        self.check_failure = ""

    @property
    def state_error(self) -> float:
        """The states' error against the optimum: the re-flight's, or the change against the check if larger."""
        return self.max_error if self.estimate is None else max(self.max_error, self.estimate.state_change)

    @property
    def objective_error_estimate(self) -> float | None:
        return None if self.estimate is None else self.estimate.objective_error

    @property
    def error(self) -> float:
        """What the loop keeps the best round by: the worse of the two estimates (unknown: infinite)."""
        obj = self.objective_error_estimate
        return max(self.state_error, math.inf if obj is None else obj)

    def record(self) -> dict:
        """This round's estimates in ``solver.refinement`` (:func:`solvers.transcription.refine.record`)."""
        obj = self.objective_error_estimate
        out = {"state_error": self.state_error if math.isfinite(self.state_error) else None,
               "objective_error_estimate": obj if obj is not None and math.isfinite(obj) else None}
        if self.estimate is not None:
            out.update(self.estimate.words())
        return out

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
        self.last_stages: Progress = solve.progress     # the stages of the latest round

    def _stages(self) -> Progress:
        """The stages of the next round: the job's own for the grid as given, refinement round k's
        (nested) for round k."""
        k, progress = len(self.trials), self.solve.progress
        return progress if k == 0 else progress.within("refinement", GRID_PLAN, round=k)

    def _round(self, problem: OcpProblem, previous, progress: Progress | None = None) -> Trial:
        if isinstance(previous, Trial):       # the check's answer is the nearer start, when there is one
            warm = (previous.fine or previous).sol.warm()
        else:
            warm = previous
        self.last_stages = progress or self._stages()
        self.trials.append(Trial(self.solve.on_grid(problem, warm, self.last_stages), problem))
        return self.trials[-1]

    def check(self, trial: Trial, progress: Progress) -> None:
        """The check solve of ``trial`` on its finer nested mesh, warm-started, and its estimate
        (:mod:`solvers.ocp.estimate`), as the ``check`` stage of ``progress`` (the round's stages); a
        check that does not converge leaves the estimate unknown."""
        stop = self.solve.should_stop
        if not trial.converged or (stop is not None and stop()):
            trial.check_failure = "the answer did not converge" if not trial.converged else "cancelled"
            return
        meshes = tuple(halved(mesh_of(ph.problem), parts_of(ph.problem.transcription)) for ph in trial.problem.phases)
        problem = on_meshes(trial.problem, meshes)
        t0 = time.perf_counter()
        fine = Trial(self.solve.on_grid(problem, trial.sol.warm(), progress.within("check", CHECK_PLAN),
                                        ipopt=CHECK_IPOPT), problem)
        if not fine.converged:
            trial.check_failure = f"the check on {fine.intervals} intervals: {fine.sol.status.message}"
            return
        trial.fine, trial.estimate = fine, estimate(trial, fine)
        trial.estimate.check_time_s = time.perf_counter() - t0

    def to_accuracy(self):
        """The loop with the accuracy planner; returns the solution to report (module docstring)."""
        problem, accuracy = self.problem, self.problem.accuracy

        def solve(meshes, previous):
            stages = self._stages()
            fine = previous.fine if isinstance(previous, Trial) else None
            if fine is not None and all(same_mesh(mesh_of(ph.problem), m) for ph, m in zip(fine.problem.phases, meshes)):
                self.trials.append(fine)          # the plan is the check's mesh: its solve is this round's
                trial = fine
            else:
                trial = self._round(on_meshes(problem, meshes), previous, stages)
            self.check(trial, stages)
            return trial

        def accept(trial: Trial) -> bool:
            obj = trial.objective_error_estimate
            return trial.sol.status.outcome is Outcome.OPTIMAL and trial.state_error <= accuracy \
                and obj is not None and obj <= accuracy

        def plan(meshes, trial: Trial, history):
            errors = [t.error for _, t in history]
            if len(errors) >= 3 and min(errors[-2:]) > STALL * min(errors[:-2]):
                return None               # two rounds without halving the error: no progress to buy
            check = None if trial.fine is None else tuple(mesh_of(ph.problem) for ph in trial.fine.problem.phases)
            if check is not None and len(errors) >= 2 and errors[-1] > STALL * min(errors[:-1]):
                # the last plan did not halve the error: where it lies was misjudged; refine everywhere
                cap = min(MAX_INTERVALS, max(STALL_FLOOR, STALL_GROWTH * history[0][1].intervals))
                return check if sum(m.intervals for m in check) <= cap else None
            out, changed = [], False
            shares = trial.estimate.shares if trial.estimate is not None else None
            total = 0.0 if trial.estimate is None else max(trial.estimate.objective_error, trial.estimate.state_change)
            for i, (ph, mesh) in enumerate(zip(trial.problem.phases, meshes)):
                view = trial.phase(i)
                held = view.verification.get("limits_held", True) and view.verification.get("terminal_held", True)
                nxt = None
                if not (view.max_error <= accuracy and held):
                    nxt = plan_phase(ph.problem.transcription, mesh, view,
                                     [(m[i], t.phase(i)) for m, t in history], accuracy)
                if shares is None:            # no estimate (its check failed): halve every interval
                    nxt = union(nxt, halved(mesh))
                elif total > accuracy:
                    nxt = union(nxt, plan_estimate(ph.problem.transcription, mesh, total * shares[i],
                                                   rf.SAFETY * accuracy, n_max=MAX_NODES))
                if nxt is not None and nxt.intervals > MAX_INTERVALS:
                    nxt = None
                out.append(mesh if nxt is None else nxt)
                changed |= nxt is not None
            if changed and check is not None and \
                    sum(m.intervals for m in out) >= CHECK_REUSE * sum(m.intervals for m in check):
                return check                  # nearly the check's mesh: its solve is there already
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
        best: Trial = out.best
        sol.solver.update(refinement=out.rounds, accuracy=accuracy_block(best, accuracy, out.reached))
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
            sol.status.message = (f"the answer's estimated error (states {err_words(best.state_error)}, objective "
                                  f"{err_words(best.objective_error_estimate)}, relative) is more than the "
                                  f"accuracy {accuracy:g} after {len(out.rounds) - 1} "
                                  f"refinement round(s) ({why}; transcription.max_refinements {max_rounds}); the "
                                  "best round is stored; accuracy_required: false accepts it with a note")
            sol.status.details["refinement"] = out.rounds
            sol.solver.update(outcome=sol.status.outcome.value, message=sol.status.message)
        return sol

    def terminal(self, rounds: int):
        """The loop without ``accuracy``: every phase's grid refined uniformly while a final value is missed."""
        problem, words = self.problem, []

        def solve(p, previous):
            return self._round(p, previous)

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
        self.check(out.best, self.last_stages)        # within the stages of the round it checks
        sol.solver["accuracy"] = accuracy_block(out.best, None, None)
        if out.best.estimate is not None:
            sol.notes.append(f"objective error estimated at {err_words(out.best.objective_error_estimate)} "
                             f"(relative), states at {err_words(out.best.state_error)} (scaled): "
                             + ESTIMATE_METHOD + f" ({out.best.estimate.check_intervals} intervals)")
        elif out.best.converged:
            sol.notes.append("objective error not estimated: " + out.best.check_failure)
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


def _round_of(out) -> int:
    for r in out.rounds:
        if r["intervals"] == out.best.intervals and r["objective"] == out.best.objective:
            return r["round"]
    return out.rounds[-1]["round"]


def rounds_summary(what: str, accuracy: float, rounds: list[dict]) -> str:
    """The note that opens a refined answer: each round's intervals and estimated errors."""
    return (f"{what} refined to the accuracy {accuracy:g}: "
            + " -> ".join(f"{r['intervals']} ({err_words(r.get('state_error'))}, "
                          f"{err_words(r.get('objective_error_estimate'))})" for r in rounds)
            + " intervals (estimated error of the states, scaled, and of the objective, relative; "
            + ESTIMATE_METHOD + ")")


def err_words(v) -> str:
    return "n/a" if v is None or not math.isfinite(v) else f"{v:.2g}"
