"""The memory a job will need, estimated from its parameters, so that a job that cannot fit under
``TRAJLAB_JOB_MEMORY_MB`` is refused with a 422 before it is queued (issue 27 item 2).

The estimate is the resident memory of the worker process that runs the job, the figure the job's
guard charges (``worker.guard``).  Each kind declares its model (``KindSpec.memory``, an
:class:`app.kinds.base.MemoryModel`): a floor (the pool process, its libraries and the solver's fixed
structures) plus what grows with the size of the problem, from runs of every preset and of grids up to
the caps in a fresh pool process (README "Limits and data" has the table).

The figures are lower estimates: :data:`MARGIN` under what was measured, so that a job refused up
front would surely have been stopped by the guard; a job near the cap is let through and the guard
decides.
"""
from __future__ import annotations

from app.runtime.settings import Settings

MARGIN = 0.9   # estimate = MARGIN x measured: 10% in the user's favour


def measured_mb(kind: str, params: dict) -> float | None:
    """The job's peak resident memory in MB as the kind's model predicts it (the measured figure, before
    :data:`MARGIN`), or None for a kind this process does not know."""
    from app.kinds import KINDS   # on first use: importing this module loads no kind package

    spec = KINDS.get(kind)
    if spec is None:
        return None
    model = spec.memory
    measured = model.floor_mb
    if model.size is not None:
        measured += model.per_unit_mb * max(model.size(params) - model.floor_size, 0.0)
    return measured


def estimate_mb(kind: str, params: dict) -> float | None:
    """A lower estimate of the job's peak resident memory in MB, or None for a kind this process does not know."""
    measured = measured_mb(kind, params)
    return None if measured is None else MARGIN * measured


class OverMemoryCap(Exception):
    """A 422: the job's estimated memory is past ``TRAJLAB_JOB_MEMORY_MB``."""

    def __init__(self, message: str):
        super().__init__(message)
        self.message = message


def check(kind: str, params: dict, settings: Settings) -> None:
    """Raise :class:`OverMemoryCap` if the job cannot fit under the cap (0: no cap)."""
    cap = settings.job_memory_mb
    need = estimate_mb(kind, params)
    if not cap or need is None or need <= cap:
        return
    from app.kinds import KINDS

    grows = KINDS[kind].memory.grows_with
    size = f" (it grows with {grows})" if grows else ""
    raise OverMemoryCap(f"this {kind} job needs about {need:.0f} MB of memory{size}, more than the cap of {cap} MB "
                        "per job (TRAJLAB_JOB_MEMORY_MB)")
