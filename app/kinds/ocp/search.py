"""Several starts of one ``ocp`` job (``search: {"starts": N}``): each start a piece of work fanned out across
the workers (``JobContext.run_pieces``), the best answer kept.

:func:`solve_start` is one start, in whichever worker takes it: the problem parsed from the job's resolved
params, the guess of that start (:func:`solvers.ocp.starts.start_guess`), the solve, and the result and
error the job would store for it.  :func:`run_search` runs them and judges: the best succeeded start's
result is the job's, with ``search: {"starts", "succeeded", "distinct_optima", "best_start", "rule", "seed",
"tolerance", "each"}``; a start that fails does not fail the job; when every start fails the job fails with
the diagnostic of the start that came closest (the smallest constraint violation), the others in ``each``.
"""
from __future__ import annotations

import math
import time
from typing import Callable

from app.kinds.base import JobContext, RunOutcome, outcome_from_status, piece
from app.kinds.ocp.advice import advice

MAX_IN_EACH = 64   # the starts listed in search.each (every start up to the setting's default cap and beyond)


def solve_one(params, problem, guess: dict | None, *, on_progress, should_stop, wall_start: float,
              warm_start: str | None) -> RunOutcome:
    """One solve of the job's problem from ``guess``: the outcome the job stores (advice on a failure)."""
    import solvers.ocp as solver

    from app.kinds.ocp.result import build_result

    sol = solver.solve(problem, initial_guess=guess, on_progress=on_progress, should_stop=should_stop)
    result = build_result(sol, params, wall_time_s=time.perf_counter() - wall_start, warm_start=warm_start)
    outcome = outcome_from_status(sol.status, result)
    if outcome.error is not None:           # what to try, by this problem's cause and transcription
        details = outcome.error.get("details") or {}
        lines = advice(outcome.error["code"], details, problem, message=outcome.error.get("message") or "",
                       result=result)
        if lines:
            outcome.error["details"] = {**details, "advice": lines}
    return outcome


@piece
def solve_start(spec: dict, index: int, should_stop: Callable[[], bool]) -> dict:
    """Start ``index`` of a job's search (module docstring); ``spec``: ``{"params", "guess", "from_job"}``."""
    from app.kinds.ocp.params import OcpParams
    from solvers.ocp.starts import start_guess

    t0 = time.perf_counter()
    params = OcpParams.model_validate(spec["params"])
    problem = params.problem
    guess = start_guess(problem, index=index, starts=problem.starts, seed=problem.seed,
                        initial_guess=spec.get("guess"))
    out = solve_one(params, problem, guess, on_progress=None, should_stop=should_stop, wall_start=t0,
                    warm_start=spec.get("from_job") if index == 0 else None)
    return {"index": index, "status": out.status, "result": out.result, "error": out.error,
            "time_s": time.perf_counter() - t0}


def _objective(entry: dict) -> float:
    v = ((entry.get("result") or {}).get("objective") or {}).get("value")
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else math.nan


def _violation(entry: dict) -> float:
    v = ((entry.get("error") or {}).get("details") or {}).get("max_constraint_violation")
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else math.inf


def _each(i: int, e: dict) -> dict:
    error = e.get("error") or {}
    if "raised" in e:
        error = {"code": "internal", "message": e["raised"]}
    solver = (e.get("result") or {}).get("solver") or {}
    ok = e.get("status") == "succeeded" and not math.isnan(_objective(e))    # a failed start's last iterate is no optimum
    return {"start": i, "status": e.get("status", "failed"), "objective": _objective(e) if ok else None,
            "iterations": solver.get("iterations"), "code": error.get("code"),
            "message": (error.get("message") or None) and str(error["message"])[:300], "by": e.get("by")}


def run_search(params, ctx: JobContext, guess: dict | None, *, from_job: str | None) -> RunOutcome:
    """The job's several starts (module docstring)."""
    from solvers.ocp.stages import SEARCH_PLAN
    from solvers.ocp.starts import RULE, distinct_optima, group_tolerance
    from solvers.progress import Progress

    problem = params.problem
    n, sense = problem.starts, problem.objective.sense
    spec = {"params": params.model_dump(mode="json", exclude_none=False), "guess": guess, "from_job": from_job}
    progress = Progress(ctx.progress, SEARCH_PLAN)
    entries = ctx.run_pieces(solve_start, spec, n, label="start",
                             on_progress=progress.stage("starts", message=f"{n} starts"))
    progress.stage("answer", message="the best start")
    if any(e.get("status") == "cancelled" for e in entries) and ctx.should_stop():
        best_partial = next((e for e in entries if e.get("result")), None)
        return RunOutcome("cancelled", result=(best_partial or {}).get("result"),
                          error={"code": "cancelled", "message": "cancelled by request"})
    good = [(i, e) for i, e in enumerate(entries) if e.get("status") == "succeeded" and not math.isnan(_objective(e))]
    tolerance = group_tolerance(problem)
    search = {"starts": n, "succeeded": len(good),
              "distinct_optima": distinct_optima([_objective(e) for _, e in good], tolerance=tolerance, sense=sense),
              "best_start": None, "rule": RULE, "seed": problem.seed, "tolerance": tolerance,
              "each": [_each(i, e) for i, e in enumerate(entries)][:MAX_IN_EACH]}
    if good:
        pick = (max if sense == "maximize" else min)(good, key=lambda ie: _objective(ie[1]))
        search["best_start"] = pick[0]
        result = dict(pick[1]["result"])
        notes = list(result.get("notes") or [])
        optima = search["distinct_optima"]
        notes.insert(0, f"best of {n} starts (start {pick[0]}; {len(good)} succeeded, {len(optima)} distinct "
                        f"optim{'um' if len(optima) == 1 else 'a'} within a relative {tolerance:g}): search.each")
        return RunOutcome("succeeded", result={**result, "search": search, "notes": notes})
    # every start failed: the one that came closest speaks for the job, the others are in search.each
    tried = [(i, e) for i, e in enumerate(entries) if e.get("error") and "raised" not in e]
    if not tried:
        raised = "; ".join(f"start {i}: {e.get('raised')}" for i, e in enumerate(entries))[:1000]
        return RunOutcome("failed", error={"code": "internal", "message": f"every start raised: {raised}",
                                           "details": {"search": search}})
    i, e = min(tried, key=lambda ie: _violation(ie[1]))
    search["best_start"] = i
    error = dict(e["error"])
    error["message"] = f"all {n} starts failed; start {i}'s (the smallest constraint violation): {error['message']}"
    error["details"] = {**(error.get("details") or {}), "search": search}
    stored = e.get("result")
    return RunOutcome("failed", result=None if stored is None else {**stored, "search": search}, error=error)
