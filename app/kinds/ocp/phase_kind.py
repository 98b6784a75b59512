"""The ``ocp`` kind's handling of several phases at the API edge: warm starts and cost.

A multi-phase problem warm-starts only from a stored multi-phase result with the same phase names
(in the same order), each phase's trajectory interpolated onto its own grid; a single phase never
starts from a multi-phase result, nor several phases from a single one.  The cost of several phases
is the sum of each phase's cost as a single phase.
"""
from __future__ import annotations

from app.kinds.base import JobFailure


def misfit(stored: dict, params: dict) -> str | None:
    """Why ``stored`` cannot start the resolved ``params`` (phase names), or None: the door's 422."""
    stored_names = [p.get("name") for p in stored.get("phases") or [] if isinstance(p, dict)]
    names = [p.get("name") for p in params.get("phases") or [] if isinstance(p, dict)]
    if not names and stored_names:
        return f"a multi-phase result (phases {stored_names}); a single phase cannot start from it"
    if names and not stored_names:
        return f"a single-phase result; a multi-phase problem starts from one with the same phases {names}"
    if names != stored_names:
        return (f"its phases are {stored_names}, this problem's {names}: the phase names must be the same, "
                "in the same order")
    return None


def check_warm_start(stored: dict, problem, *, job_id: str, field: str) -> None:
    """A :class:`JobFailure` (``invalid_input``) naming ``field`` and the reason when ``stored`` cannot
    start ``problem``."""
    stored_names = [p.get("name") for p in stored.get("phases") or [] if isinstance(p, dict)]
    names = list(getattr(problem, "phase_names", ()) or ())
    if not names and stored_names:
        raise JobFailure("invalid_input", f"{field}: job {job_id} is a multi-phase result (phases "
                                          f"{stored_names}); a single phase cannot start from it")
    if names and not stored_names:
        raise JobFailure("invalid_input", f"{field}: job {job_id} is a single-phase result; a multi-phase "
                                          f"problem starts from one with the same phases {names}")
    if names and stored_names != names:
        raise JobFailure("invalid_input", f"{field}: job {job_id} has the phases {stored_names}, this problem "
                                          f"{names}: the phase names must be the same, in the same order")
    for p in stored.get("phases") or []:
        tr = p.get("trajectory") if isinstance(p, dict) else None
        if not (isinstance(tr, dict) and hasattr(tr.get("t"), "__len__") and len(tr["t"]) >= 2):
            raise JobFailure("invalid_input", f"{field}: job {job_id}'s phase {p.get('name')} has no trajectory")


def phases_cost(params: dict, cost_one) -> float:
    """The sum over the phases of ``cost_one`` of each phase as a single-phase body."""
    integrand = (params.get("objective") or {}).get("integrand")
    total = 0.0
    for ph in params.get("phases") or []:
        if not isinstance(ph, dict):
            continue
        mine = integrand.get(ph.get("name")) if isinstance(integrand, dict) else integrand
        total += cost_one({**ph, "objective": {"integrand": mine}, "accuracy": params.get("accuracy")})
    return total
