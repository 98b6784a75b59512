"""Mesh refinement of several ``ocp`` phases to a stated ``accuracy``: one mesh per phase, one loop.

The loop is :func:`solvers.transcription.refine.refine` (as for one phase, :mod:`solvers.ocp.refine`)
with a tuple of meshes, one per phase: each round solves all phases as one NLP
(:mod:`solvers.ocp.multisolve`), warm-started from the previous round's phases, and each phase's
mesh is planned by the single phase's planner (:func:`solvers.ocp.refine.planner`) from that
phase's own interval errors (its intervals re-flown each from its first node) and path excesses;
a phase already within the accuracy keeps its mesh.  The worst scaled state error over the phases
is the round's error; the loop stops when every phase meets the accuracy (and the solve is
optimal: limits and terminal values held), when ``max_refinements`` rounds (the largest of the
phases') are spent, or when no phase can be refined.  Not reaching it ends ``accuracy_not_reached``
with the best round stored, unless ``accuracy_required`` is false (then a note).
"""
from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

from solvers.common import Outcome
from solvers.ocp import refine as one
from solvers.transcription import refine as rf


class PhasesTrial:
    """One round: the multi-phase solution, its problem and each phase seen as a single-phase trial."""

    def __init__(self, sol, problem):
        self.sol, self.problem = sol, problem
        ver = sol.verification
        self.converged = sol.status.outcome in (Outcome.OPTIMAL, Outcome.LIMIT_NOT_HELD,
                                                Outcome.TERMINAL_NOT_HELD) and bool(ver.get("ok"))
        err = ver.get("max_state_difference_scaled_overall")
        self.max_error = float(err) if err is not None and math.isfinite(err) else math.inf
        self.objective = sol.objective
        self.iterations = sol.status.iterations
        self.intervals = sum(p.problem.transcription.intervals for p in problem.phases)
        self._views: dict[int, SimpleNamespace] = {}

    def phase(self, i: int) -> SimpleNamespace:
        """Phase ``i`` as the single-phase planner reads a trial (its local errors computed once)."""
        if i not in self._views:
            p, errs = self.sol.phases[i], self.sol.interval_errors[i]
            err = p["verification"].get("max_state_difference_scaled_overall")
            state = errs["state"]
            self._views[i] = SimpleNamespace(
                sol=SimpleNamespace(verification=p["verification"]), interval_excess=errs["path"],
                max_error=float(err) if err is not None and math.isfinite(err) else math.inf,
                interval_error=state() if callable(state) else state)
        return self._views[i]


def solve_phases_refined(problem, *, solve_once, initial_guess, should_stop, **kw):
    """The refinement loop over the phases' meshes (module docstring); returns the solution to report."""
    accuracy = problem.accuracy
    trials: list[PhasesTrial] = []

    def on_meshes(meshes):
        return replace(problem, phases=tuple(replace(ph, problem=one.on_mesh(ph.problem, m))
                                             for ph, m in zip(problem.phases, meshes)))

    def solve(meshes, previous):
        mp = on_meshes(meshes)
        warm = previous if not isinstance(previous, PhasesTrial) else \
            {"phases": previous.sol.phases, "parameters": previous.sol.parameters}
        trials.append(PhasesTrial(solve_once(mp, warm, should_stop=should_stop, **kw), mp))
        return trials[-1]

    def accept(trial):
        return trial.sol.status.outcome is Outcome.OPTIMAL and trial.max_error <= accuracy

    def plan(meshes, trial, history):
        out, changed = [], False
        for i, (ph, mesh) in enumerate(zip(trial.problem.phases, meshes)):
            view = trial.phase(i)
            held = view.sol.verification.get("limits_held", True) and view.sol.verification.get("terminal_held", True)
            if view.max_error <= accuracy and held:
                out.append(mesh)
                continue
            hist = [(m[i], t.phase(i)) for m, t in history]
            nxt = one.planner(replace(ph.problem, accuracy=accuracy))(mesh, view, hist)
            out.append(mesh if nxt is None else nxt)
            changed |= nxt is not None
        return tuple(out) if changed else None

    rounds = max(ph.problem.transcription.max_refinements for ph in problem.phases)
    res = rf.refine(mesh=tuple(one.mesh_of(ph.problem) for ph in problem.phases), solve=solve, accept=accept,
                    plan=plan, max_rounds=rounds, should_stop=should_stop, previous=initial_guess)
    sol = res.best.sol
    if len(trials) > 1:
        st = sol.status
        st.iterations = sum(t.sol.status.iterations for t in trials)
        st.solve_time_s = sum(t.sol.status.solve_time_s for t in trials)
        st.build_time_s = sum(t.sol.status.build_time_s for t in trials)
        sol.solver.update(iterations=st.iterations, solve_time_s=st.solve_time_s, build_time_s=st.build_time_s)
    sol.solver.update(refinement=res.rounds, accuracy=accuracy, accuracy_reached=res.reached)
    summary = one.rounds_summary("every phase's mesh", accuracy, res.rounds) + " over all phases"
    if res.reached:
        sol.notes.insert(0, summary + "; reached")
        return sol
    why = res.stopped or "not reached"
    sol.notes.insert(0, summary + f"; NOT reached ({why})")
    if sol.status.outcome in (Outcome.OPTIMAL, Outcome.TERMINAL_NOT_HELD) and problem.accuracy_required:
        sol.status.outcome = Outcome.ACCURACY_NOT_REACHED
        sol.status.message = (f"the re-flown states depart from the answer by {one.err_words(res.best.max_error)} (scaled), "
                              f"more than the accuracy {accuracy:g}, after {len(res.rounds) - 1} refinement "
                              f"round(s) ({why}); the best round is stored; accuracy_required: false accepts it "
                              "with a note")
        sol.status.details["refinement"] = res.rounds
        sol.solver["outcome"] = sol.status.outcome.value
        sol.solver["message"] = sol.status.message
    return sol

