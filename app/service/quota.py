"""Per-owner quotas and the quick/heavy queue choice, from a cost estimate of each job's parameters.

The cost is a size measure in "work units", not a time: one unit is about one
RK4 step of one shooting interval of the reentry NLP, so the Betts reentry
preset (100 intervals x 2 substeps) costs 200.  Each kind's formula grows with
the parameters that drive its run time:

* ``reentry``: intervals x substeps;
* ``robust_reentry``: 10 x intervals x substeps (18 sensitivity equations per
  state, three continuation stages) x (1 + Monte Carlo samples / 1000);
* ``midcourse``: optimize: population x generations x max(1, dispersion samples) / 5
  (one J2 propagation per member and generation); evaluate: schedules x samples;
* ``intercept``: scan and porkchop points / 100, plus 200 per finite-thrust
  mesh (1 + max_refinements), twice that with a free final time;
* a kind that declares ``KindSpec.cost`` (``ocp``: intervals x steps per interval x (states +
  controls) x the expressions' size, scaled so that the Betts shuttle written as an ocp costs what
  the reentry kind's does; ``app.kinds.ocp.kind.cost``).

A submission is refused with 429 (and ``Retry-After``) when its owner already
has ``max_queued_per_owner`` queued jobs, ``max_active_per_owner`` queued plus
running jobs, or when its cost would take the owner's queued plus running cost
past ``max_active_cost_per_owner``.  A job whose cost alone exceeds that budget
is still admitted when the owner has nothing else active: the per-field caps of
each kind bound it, and refusing it would refuse it forever.  With
``max_stored_mb_per_owner`` set, a submission is also refused while the owner's jobs keep that much
(params and compressed results: ``jobs.stored_bytes``, app.service.storage) until some are deleted.
With auth off (one local user, owner None) no quota applies.

Jobs costing more than ``heavy_cost``, and every ``robust_reentry``, go to the
heavy queue, so quick jobs never wait behind them (workers per queue: README).
"""
from __future__ import annotations

import math

from sqlalchemy import Connection
from sqlalchemy.orm import Session

from app.service import jobs, storage
from app.service.broker import QUEUE_HEAVY, QUEUE_JOBS
from app.runtime.db import Database
from app.runtime.settings import Settings

ALWAYS_HEAVY = frozenset({"robust_reentry"})


def _reentry_cost(p: dict) -> float:
    grid = p.get("grid") or {}
    # with accuracy, each refinement round may solve again (on more intervals), as ocp's cost counts
    rounds = 1.0 + (float(grid.get("max_refinements", 8)) if p.get("accuracy") else 0.0)
    return float(grid.get("intervals", 100)) * float(grid.get("substeps", 2)) * rounds


def _robust_cost(p: dict) -> float:
    samples = float((p.get("monte_carlo") or {}).get("samples", 0))
    return 10.0 * _reentry_cost(p) * (1.0 + samples / 1000.0)


def _midcourse_cost(p: dict) -> float:
    samples = max(1.0, float((p.get("dispersion") or {}).get("samples", 1)))
    if p.get("mode") == "evaluate":
        return float(len(p.get("schedules") or [])) * samples
    return float(p.get("population", 100)) * float(p.get("generations", 500)) * samples / 5.0


def _intercept_cost(p: dict) -> float:
    cost = 0.0
    methods = p.get("methods") or []
    if "impulsive" in methods:
        scan = p.get("scan") or {}
        start = float(scan.get("t_start_s") or 0.0)
        end = scan.get("t_end_s") or p.get("intercept_time_s") or 0.0
        step = float(scan.get("step_s") or 1.0)
        cost += max(0.0, float(end) - start) / step / 100.0
        porkchop = p.get("porkchop") or {}
        if porkchop.get("enabled"):
            cost += float(porkchop.get("t_man_points", 0)) * float(porkchop.get("t_intercept_points", 0)) / 100.0
    if "finite_thrust" in methods:
        meshes = 1.0 + float((p.get("finite_thrust") or {}).get("max_refinements", 3))
        cost += 200.0 * meshes * (2.0 if p.get("free_final_time") else 1.0)
    return cost


_COSTS = {"reentry": _reentry_cost, "robust_reentry": _robust_cost,
          "midcourse": _midcourse_cost, "intercept": _intercept_cost}


def estimate_cost(kind: str, params: dict) -> float:
    """Work units of a job from its resolved parameters (see the module docstring)."""
    if kind in _COSTS:
        cost = _COSTS[kind](params)
    else:  # a kind that declares its own (KindSpec.cost)
        from app.kinds import KINDS

        own = getattr(KINDS.get(kind), "cost", None)
        cost = float(own(params)) if own is not None else 0.0
    return cost if math.isfinite(cost) else math.inf


def queue_for(kind: str, cost: float, settings: Settings) -> str:
    return QUEUE_HEAVY if kind in ALWAYS_HEAVY or cost > settings.heavy_cost else QUEUE_JOBS


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
