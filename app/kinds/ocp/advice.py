"""What to try when an ``ocp`` job fails, chosen by the cause and by the problem's own transcription.

The shared advice (:data:`app.kinds.failures.ADVICE`) speaks of every kind at once; an ``ocp`` problem is
written as data, so its advice names its own fields (``transcription.method``, ``accuracy``, the states'
``scale`` and bounds, the entries the message names) and never another kind's (a heating limit, a
``terminal_check``).  A method is recommended only to a job that does not already use it; an answer verified
interval by interval because its dynamics amplify errors (``verification.mode``, :mod:`solvers.ocp.growth`)
is told so first, with the growth, since no grid makes a flight from t0 follow it.  The run stores the list
in the error's ``details.advice``; :func:`app.kinds.failures.explain` shows it.
"""
from __future__ import annotations

from app.kinds.ocp.warm_start import WARM_START_FIELD

INVALID_NUMBER = "Invalid_Number_Detected"    # IPOPT's word for an overflow or NaN it was handed

_BETTER_GUESS = ("Start nearer the answer: initial_guess.states and initial_guess.controls (first and last "
                 f"values), or {WARM_START_FIELD} from a solved nearby problem (a shorter horizon, a looser constraint).")
_SCALE = ("Give each state and control a scale (states[].scale) and the bounds it physically keeps "
          "(lower, upper), so no iterate can wander where an expression overflows or is undefined.")


def _methods(problem) -> set[str]:
    return {ph.problem.phase.transcription.method for ph in problem.phases}


def _invalid_number(problem) -> list[str]:
    out = []
    if "multiple_shooting" in _methods(problem):
        out.append("Multiple shooting integrates the dynamics with explicit RK4 steps (transcription.substeps "
                   "per interval) from the guess; on fast or stiff dynamics a step this long overflows. Use "
                   "transcription.method \"lgl\" (collocation takes no explicit steps), with accuracy set so "
                   "the grid is refined where the answer needs it, or more transcription.intervals or "
                   "substeps so every step is short.")
    if "lgl" in _methods(problem):
        out.append("With LGL collocation the overflow comes from an expression at the guess or an iterate (a "
                   "division by a state that reaches zero, a sqrt or log of a negative value, exp of a large "
                   "one): bound the states it depends on away from there.")
    return out + [_SCALE, _BETTER_GUESS]


def _violated(problem, details: dict) -> list[str]:
    named = [v["name"] for v in details.get("violations") or [] if isinstance(v, dict)]
    first = (f"The message names what stayed violated ({', '.join(named[:3])}) with its worst value and time: "
             "relax that entry's lower or upper, or the initial and final values and bounds that force it."
             if named else
             "The message says where the dynamics do not join up: the initial and final values and the "
             "bounds of the states there may not be reachable together.")
    return [first, "Solve once without the entry (remove it from path or boundary), then put it back with "
                   f"{WARM_START_FIELD} from that job."]


def _other_method(problem) -> list[str]:
    methods = _methods(problem)
    if methods == {"multiple_shooting"}:
        return ["Try transcription.method \"lgl\" with accuracy set: collocation is often easier for IPOPT "
                "on long horizons and stiff dynamics."]
    if methods == {"lgl"}:
        return ["Try transcription.method \"multiple_shooting\": integrated intervals are more robust to a "
                "poor guess on smooth, non-stiff dynamics."]
    return []


def amplifying(result: dict | None) -> dict | None:
    """The growth figure of the first phase whose answer was verified interval by interval because its
    dynamics amplify errors (``verification.mode``), else None."""
    blocks = [result or {}] + list((result or {}).get("phases") or [])
    for b in blocks:
        ver = b.get("verification") if isinstance(b, dict) else None
        if isinstance(ver, dict) and ver.get("mode") == "interval_by_interval":
            return ver.get("growth") or {}
    return None


def _amplify(growth: dict) -> str:
    g = growth.get("exponent")
    figure = f"by about e^{g:.3g}" if isinstance(g, (int, float)) else "strongly"
    return (f"The dynamics amplify errors {figure} over the phase (verification.growth), so the answer was "
            "verified interval by interval from its nodes (verification.mode); a flight of these controls from "
            "the initial state diverges whatever the grid. Refining helps only where an interval's own defect "
            "is large: set accuracy, or add transcription.intervals there.")


def _reflight_failed() -> list[str]:
    return ["The independent re-flight of the answer's controls stopped at the interval the message names: "
            "an expression of the dynamics is not finite there on the re-flown states (a division by a state "
            "that reaches zero, a sqrt or log of a negative value, exp of a large one). Bound those states "
            "(states[].lower, upper) so the answer keeps away from there.",
            "Add transcription.intervals, or set accuracy, so the answer between the nodes is what the "
            "re-flight flies."]


def advice(code: str, details: dict, problem, *, message: str = "", result: dict | None = None) -> list[str] | None:
    """The lines of "what to try" for an ``ocp`` failure with error ``code``, ``message`` and ``details`` on
    ``problem`` (:class:`solvers.ocp.problem.OcpProblem`), its stored ``result`` read for the verification's
    mode; None where the shared advice of the code fits as it is."""
    if details.get("solver_status") == INVALID_NUMBER:
        return _invalid_number(problem)
    if code == "solver_failed" and "re-propagation failed" in message:
        return _reflight_failed()
    lines = _by_code(code, details, problem)
    growth = amplifying(result)
    if growth is not None and code in ("terminal_not_held", "accuracy_not_reached", "limit_not_held"):
        return [_amplify(growth)] + (lines or [])
    return lines


def _by_code(code: str, details: dict, problem) -> list[str] | None:
    if code in ("infeasible", "not_converged"):
        extra = [_BETTER_GUESS] + _other_method(problem) if code == "not_converged" else []
        return _violated(problem, details) + extra
    if code == "limit_not_held":
        return ["Add transcription.intervals, or set accuracy: the grid is then refined where the limit is "
                "exceeded between the nodes.",
                "Tighten the path entry by its reported excess so the answer keeps the original one between "
                "the nodes."]
    if code == "terminal_not_held":
        return ["Add transcription.intervals (or substeps with multiple shooting, nodes with LGL), or set "
                "accuracy: the transcription's integration error shows at the end.",
                "Check that the final values asked are reachable to the tolerance the result reports."]
    if code == "accuracy_not_reached":
        return ["Allow more refinement rounds (transcription.max_refinements) or start from more "
                "transcription.intervals.",
                "Ask for a looser accuracy; the last answer and its error estimate are in the stored result."
                ] + _other_method(problem)
    return None
