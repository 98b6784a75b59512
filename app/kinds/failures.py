"""A failed job explained in the user's terms: what went wrong, where (the time, when the solver's
diagnostic names an interval and the stored last iterate has the grid), whether it was proved before any
iteration, and what to try, per error code.

The job page (``GET /console/jobs/{id}/summary``) and ``trajlab wait`` print this; docs/failures.md
("When a job fails") is the long form of :data:`ADVICE` and keeps its headings in step with the codes.
"""
from __future__ import annotations

import re

# The error codes a job can be stored with, one sentence each on what the code means to the user. This is
# the one declaration: the OpenAPI enum (app.api.schemas.ErrorCode), the store's check (app.service.jobs)
# and ADVICE derive from or are checked against it (tests/unit/test_error_codes.py).
WHAT = {
    "infeasible": "The problem as posed has no solution: the solver (or a proof before it) found that the "
                  "constraints cannot all hold at once.",
    "not_converged": "The solver stopped before it found an answer (iteration limit or no progress). The "
                     "problem may be infeasible, badly scaled, or started from a poor guess.",
    "limit_not_held": "The optimizer converged, but the re-propagation between the nodes broke a path limit "
                      "by more than its tolerance.",
    "terminal_not_held": "The optimizer converged, but the re-propagated controls miss a requested final value "
                         "by more than its tolerance.",
    "accuracy_not_reached": "The solver converged, but the mesh refinement could not bring the "
                            "transcription's error below the requested accuracy within its rounds.",
    "not_robust": "The robust design did not keep the heating limit in the share of Monte Carlo samples the "
                  "confirmation accepts.",
    "numerical_overflow": "The problem's own expressions, or the transcription's integration of its dynamics, "
                          "gave an overflow or NaN (IPOPT's Invalid_Number_Detected) at the guess or an iterate, "
                          "and a guess built by integrating the dynamics did not avoid it. The problem, its "
                          "guess or its transcription has to change; trajlab did not fail.",
    "time_limit": "The job ran out of its time limit before the solver finished.",
    "resource_limit": "The job needed more memory than one job may hold (TRAJLAB_JOB_MEMORY_MB); it was "
                      "stopped, and is not retried.",
    "worker_lost": "The worker running the job stopped (restart or crash) more often than the retry budget allows.",
    "solver_failed": "The solver stopped on an error of its own (a numerical failure such as a NaN in the "
                     "model, or problem data it found unusable late), neither an answer nor a verdict on the "
                     "problem. The message gives the solver's own status.",
    "invalid_input": "A field validated but names something unusable when the job runs (e.g. a warm start "
                     "from a job that cannot serve as one).",
    "internal": "A bug in trajlab: the job hit an error nobody planned for. The message names it; please report it.",
    "cancelled": "The job was cancelled on request.",
}

ERROR_CODES: tuple[str, ...] = tuple(WHAT)

# What to try, per code, most useful first.
ADVICE = {
    "infeasible": [
        "Read the message: it names the constraint that cannot be met and by how much.",
        "Relax that constraint (a terminal value, a path limit such as path.max_heat_rate_w_m2) or widen the "
        "control bounds that keep the vehicle from meeting it.",
        "A reentry heating or dynamic-pressure limit below what the pinned entry or final state allows is "
        "proved impossible before any iteration (solver status pinned_end_bound): raise the limit or change "
        "that state.",
    ],
    "not_converged": [
        "Look at the last iterate's plots below: the worst defect names the state and the time where the "
        "trajectory does not join up.",
        "Check the limits first: a limit that cannot be met often shows up as non-convergence. Solve once "
        "without it (set it to null), then put it back with a warm start from that job.",
        "Warm-start from a succeeded job of a nearby problem (initial_guess.from_job).",
        "Refine or coarsen the grid (grid.intervals, transcription.intervals); widen tight bounds a little.",
    ],
    "limit_not_held": [
        "Add grid intervals (the limit is enforced at RK4 step points; finer steps follow it closer).",
        "Tighten the limit by its reported excess so the answer keeps the original one between the nodes.",
    ],
    "terminal_not_held": [
        "Add grid intervals or substeps: the transcription's integration error shows at the end.",
        "Check the terminal tolerances (terminal_check) against what the integrator can deliver.",
    ],
    "accuracy_not_reached": [
        "Allow more refinement rounds (transcription.max_refinements) or start from more intervals.",
        "Ask for a looser accuracy; the last answer and its error estimate are in the stored result.",
    ],
    "not_robust": [
        "Raise heat_margin or k_constraint so the robust design keeps a wider margin from the limit.",
        "Allow more confirmation rounds (confirmation.max_rounds) or more samples for a tighter estimate.",
    ],
    "numerical_overflow": [
        "Read the message: it says whether the overflow came at the first guess or at a later iterate.",
        "Bound the states an expression depends on away from where it overflows or is undefined (a division "
        "by a state that reaches zero, a sqrt or log of a negative value, exp of a large one), and give each "
        "state a scale.",
        "With multiple shooting, shorter RK4 steps (more intervals or substeps) or collocation (LGL) keep fast "
        "or stiff dynamics from overflowing; or start from a better guess (initial_guess.from_job).",
    ],
    "time_limit": [
        "Make the problem smaller (fewer intervals, samples or generations) or raise the kind's time limit "
        "(TRAJLAB_TIME_LIMIT_<KIND>_S, an operator setting).",
    ],
    "resource_limit": [
        "Make the problem smaller: fewer grid intervals or substeps (the memory grows with them); the message "
        "gives the cap and the memory reached.",
        "Or ask the operator for a larger TRAJLAB_JOB_MEMORY_MB (fewer jobs then run at once on a worker).",
    ],
    "worker_lost": ["Re-run the job; if it happens again, tell the operator (the worker's logs say why)."],
    "solver_failed": [
        "Read the solver status in the message: an evaluation error (NaN or Inf) points at the model, e.g. a "
        "square root or a division that reaches zero, or an atmosphere or table left outside its range.",
        "Tighten the bounds that let the iterate wander there, or start from a better guess "
        "(initial_guess.from_job).",
    ],
    "invalid_input": ["Fix the field the message names and submit again."],
    "internal": ["Report the job id and the message; re-running will most likely fail the same way."],
    "cancelled": ["Re-run it when you want the answer."],
}

_INTERVAL = re.compile(r"at interval (\d+)")


def _time_of_interval(message: str, result: dict | None) -> float | None:
    """The start time of the interval the solver's message names, from the stored last iterate's grid."""
    m = _INTERVAL.search(message or "")
    t = ((result or {}).get("trajectory") or {}).get("t_s") or ((result or {}).get("trajectory") or {}).get("t")
    if not m or not isinstance(t, list):
        return None
    j = int(m.group(1))
    return t[j] if 0 <= j < len(t) and isinstance(t[j], (int, float)) else None


def explain(error: dict | None, result: dict | None = None) -> dict | None:
    """``{code, what, message, where, proved, advice}`` of a failed job's ``error``; None without one."""
    if not error:
        return None
    code = error.get("code") or "internal"
    message = error.get("message") or ""
    details = error.get("details") or {}
    where = None
    t = _time_of_interval(message, result)
    if t is not None:
        where = f"around t = {t:.1f} s into the flight (the interval the message names)"
    proved = details.get("solver_status") == "pinned_end_bound" or "certificate" in details
    # a kind that knows the cause and the problem's own fields stores its advice with the error
    # (app/kinds/<kind>/advice.py); the shared lines of the code are the fallback
    own = details.get("advice")
    kind_advice = own if isinstance(own, list) and own and all(isinstance(a, str) for a in own) else None
    return {"code": code, "what": WHAT.get(code, WHAT["internal"]), "message": message, "where": where,
            "proved": bool(proved), "iterations": details.get("iterations"),
            "advice": kind_advice or ADVICE.get(code, ADVICE["internal"]), "guide": "/guide/failures/"}


def as_lines(explained: dict) -> list[str]:
    """The explanation as the CLI prints it."""
    lines = [f"{explained['code']}: {explained['message']}", explained["what"]]
    if explained["proved"]:
        lines.append("This was proved before any iteration: no setting of the solver will change it.")
    if explained["where"]:
        lines.append(f"Where: {explained['where']}.")
    lines.append("What to try:")
    lines += [f"  - {a}" for a in explained["advice"]]
    lines.append(f"More: {explained['guide']} (the service's guide, 'When a job fails').")
    return lines
