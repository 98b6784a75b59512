"""Warm starts of the ``ocp`` kind (``initial_guess.from_job``), one rule for one phase and several.

A stored result starts a problem of the same form: a problem posed as one phase starts from a
single-phase result (its ``trajectory``), one of several phases from a multi-phase result with the
same phase names in the same order (each phase's trajectory interpolated onto its own grid).
:func:`misfit` is the door's 422 (on the resolved params, before anything is stored);
:func:`load_warm_start` the run's check on the loaded result (a clean ``invalid_input`` naming the
field, never ``internal``).
"""
from __future__ import annotations

from app.kinds.base import JobContext, JobFailure

WARM_START_FIELD = "initial_guess.from_job"


def _stored_names(stored: dict) -> list:
    return [p.get("name") for p in stored.get("phases") or [] if isinstance(p, dict)]


def _fit(stored_names: list, names: list) -> str | None:
    if not names and stored_names:
        return f"a multi-phase result (phases {stored_names}); a single phase cannot start from it"
    if names and not stored_names:
        return f"a single-phase result; a multi-phase problem starts from one with the same phases {names}"
    if names != stored_names:
        return (f"its phases are {stored_names}, this problem's {names}: the phase names must be the same, "
                "in the same order")
    return None


def misfit(stored: dict, params: dict) -> str | None:
    """Why ``stored`` cannot start the resolved ``params`` (phase names), or None: the door's 422."""
    return _fit(_stored_names(stored), [p.get("name") for p in params.get("phases") or [] if isinstance(p, dict)])


def check_warm_start(stored: dict, problem, *, job_id: str, field: str = WARM_START_FIELD) -> None:
    """A :class:`JobFailure` (``invalid_input``) naming ``field`` and the reason when ``stored`` cannot
    start ``problem`` (:class:`solvers.ocp.OcpProblem`)."""
    names = [] if problem.single else list(problem.phase_names)
    why = _fit(_stored_names(stored), names)
    if why is not None:
        raise JobFailure("invalid_input", f"{field}: job {job_id} is {why}" if why.startswith("a ")
                         else f"{field}: job {job_id}: {why}")
    blocks = (stored.get("phases") or []) if names else [stored]  # (_fit saw the phases)
    for p in blocks:
        tr = p.get("trajectory") if isinstance(p, dict) else None
        if not (isinstance(tr, dict) and hasattr(tr.get("t"), "__len__") and len(tr["t"]) >= 2):
            where = f" (phase {p.get('name')})" if names and isinstance(p, dict) else ""
            raise JobFailure("invalid_input", f"{field}: job {job_id} has no ocp trajectory to start from{where}")


def load_warm_start(ctx: JobContext, job_id: str, problem) -> dict:
    """The stored result of another ``ocp`` job that fits ``problem``, or a :class:`JobFailure`."""
    try:
        stored = ctx.load_result(job_id)
    except LookupError as exc:
        raise JobFailure("invalid_input", f"{WARM_START_FIELD}: {exc}") from None
    if not isinstance(stored, dict):
        raise JobFailure("invalid_input", f"{WARM_START_FIELD}: job {job_id} has no ocp trajectory to start from")
    check_warm_start(stored, problem, job_id=job_id)
    return stored
