"""Per-owner quotas and the quick/heavy queue choice, from a cost estimate of each job's parameters.

The cost is a size measure in "work units", not a time: one unit is about one
RK4 step of one shooting interval of the reentry NLP, so the Betts reentry
preset (100 intervals x 2 substeps) costs 200.  Each kind declares its formula
(``KindSpec.cost``), growing with the parameters that drive its run time
(the reentry family: intervals x substeps; ``midcourse``: population x
generations; ``intercept``: scan points and finite-thrust meshes; ``ocp``:
steps x states and controls x the expressions' size; each kind's ``cost``
docstring has its formula).

A submission is refused with 429 (and ``Retry-After``) when its owner already
has ``max_queued_per_owner`` queued jobs, ``max_active_per_owner`` queued plus
running jobs, or when its cost would take the owner's queued plus running cost
past ``max_active_cost_per_owner``.  A job whose cost alone exceeds that budget
is still admitted when the owner has nothing else active: the per-field caps of
each kind bound it, and refusing it would refuse it forever.  With
``max_stored_mb_per_owner`` set, a submission is also refused while the owner's jobs keep that much
(params and compressed results: ``jobs.stored_bytes``, app.service.storage) until some are deleted.
With auth off (one local user, owner None) no quota applies.

Jobs costing more than ``heavy_cost``, and every job of a kind that says so
(``KindSpec.always_heavy``), go to the heavy queue, so quick jobs never wait
behind them (workers per queue: README).
"""
from __future__ import annotations

import math

from sqlalchemy import Connection
from sqlalchemy.orm import Session

from app.service import jobs, storage
from app.service.broker import QUEUE_HEAVY, QUEUE_JOBS
from app.runtime.db import Database
from app.runtime.settings import Settings


def estimate_cost(kind: str, params: dict) -> float:
    """Work units of a job from its resolved parameters (``KindSpec.cost``; see the module docstring); 0 for
    a kind this process does not know (a job row left by a kind since removed)."""
    from app.kinds import KINDS   # on first use: importing the quota loads no kind package

    spec = KINDS.get(kind)
    cost = float(spec.cost(params)) if spec is not None else 0.0
    return cost if math.isfinite(cost) else math.inf


def queue_for(kind: str, cost: float, settings: Settings) -> str:
    from app.kinds import KINDS

    spec = KINDS.get(kind)
    always = spec is not None and spec.always_heavy
    return QUEUE_HEAVY if always or cost > settings.heavy_cost else QUEUE_JOBS


class QuotaExceeded(Exception):
    """A 429: the owner is over one of its limits; ``retry_after_s`` goes in ``Retry-After``."""

    def __init__(self, message: str, retry_after_s: int):
        super().__init__(message)
        self.message = message
        self.retry_after_s = retry_after_s


def check_quota(db: Database, settings: Settings, *, owner: str | None, cost: float) -> None:
    """Raise :class:`QuotaExceeded` if ``owner`` may not queue a job of ``cost`` now."""
    if owner is None:
        return
    with db.read() as s:
        check_quota_in(s, settings, owner=owner, cost=cost)


def check_quota_in(session: Session | Connection, settings: Settings, *, owner: str | None, cost: float) -> None:
    """:func:`check_quota` inside the caller's transaction (``jobs.create_job``'s ``admit``)."""
    if owner is None:
        return
    active = jobs.active_jobs(session, owner)
    queued = sum(1 for j in active if j.status == "queued")
    used = sum(estimate_cost(j.kind, j.params) for j in active)
    retry = settings.quota_retry_after_s
    if queued >= settings.max_queued_per_owner:
        raise QuotaExceeded(f"{queued} jobs already queued; at most {settings.max_queued_per_owner} per owner "
                            "(TRAJLAB_MAX_QUEUED_PER_OWNER)", retry)
    if len(active) >= settings.max_active_per_owner:
        raise QuotaExceeded(f"{len(active)} jobs already queued or running; at most "
                            f"{settings.max_active_per_owner} per owner (TRAJLAB_MAX_ACTIVE_PER_OWNER)", retry)
    if active and used + cost > settings.max_active_cost_per_owner:
        raise QuotaExceeded(f"estimated cost {cost:.0f} on top of {used:.0f} queued or running would pass the "
                            f"budget of {settings.max_active_cost_per_owner:.0f} per owner "
                            "(TRAJLAB_MAX_ACTIVE_COST_PER_OWNER)", retry)
    cap = storage.max_stored_bytes(settings)
    if cap is not None:
        stored = storage.owner_stored_bytes(session, owner)
        if stored >= cap:
            raise QuotaExceeded(f"this owner's jobs keep {stored / storage.MB:.1f} MiB; at most "
                                f"{settings.max_stored_mb_per_owner:g} MiB per owner "
                                "(TRAJLAB_MAX_STORED_MB_PER_OWNER): delete jobs (DELETE /v1/jobs/{id}, "
                                "trajlab delete) to submit more", retry)
