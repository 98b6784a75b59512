"""The memory a job will need, estimated from its parameters, so that a job that cannot fit under
``TRAJLAB_JOB_MEMORY_MB`` is refused with a 422 before it is queued (issue 27 item 2).

The estimate is the resident memory of the worker process that runs the job, the figure the job's
guard charges (``worker.guard``): a floor per kind (the pool process, its libraries and the solver's
fixed structures) plus what grows with the size of the problem, from runs of every preset and of
grids up to the caps in a fresh pool process (README "Limits and data" has the table):

* ``reentry``: per interval of the grid: the peak is at the end, in the dense re-propagation and the
  result (the NLP itself grows little: 151 MB at 1000 intervals x 16 substeps while IPOPT runs);
* ``robust_reentry``: per interval x substeps of the augmented (18 sensitivity equations per state)
  system; the Monte Carlo runs in chunks, so its samples do not add to the peak;
* ``ocp``: per RK4 step (or LGL node) x (states + controls);
* ``midcourse`` and ``intercept``: their floors (their fields are capped below where memory grows).

The figures are lower estimates: :data:`MARGIN` under what was measured, so that a job refused up
front would surely have been stopped by the guard; a job near the cap is let through and the guard
decides.  Where the cap is not known here (a kind without a formula) nothing is refused.
"""
from __future__ import annotations

from app.runtime.settings import Settings

MARGIN = 0.9   # estimate = MARGIN x measured: 10% in the user's favour

# Resident memory (MB) of each kind's preset in a fresh pool process, measured, and what one unit of size
# adds (from grids up to the caps); the growth counts from the preset's size.
FLOOR_MB = {"reentry": 167.0, "robust_reentry": 397.0, "ocp": 215.0, "midcourse": 343.0, "intercept": 356.0}
FLOOR_SIZE = {"reentry": 100.0, "robust_reentry": 200.0, "ocp": 100.0 * 2 * 8}
PER_UNIT_MB = {"reentry": 0.12, "robust_reentry": 0.06, "ocp": 0.0003}


def _reentry_size(p: dict) -> float:
    return float((p.get("grid") or {}).get("intervals", 100))


def _robust_size(p: dict) -> float:
    grid = p.get("grid") or {}
    return float(grid.get("intervals", 100)) * float((p.get("robust") or {}).get("substeps", 2))


def _ocp_size(p: dict) -> float:
    tr = p.get("transcription") or {}
    if tr.get("method", "multiple_shooting") == "multiple_shooting":
        steps = float(tr.get("substeps", 2))
    else:
        steps = float(tr.get("nodes", 4))
    width = float(len(p.get("states") or []) + len(p.get("controls") or []))
    return float(tr.get("intervals", 50)) * steps * width


_SIZES = {"reentry": _reentry_size, "robust_reentry": _robust_size, "ocp": _ocp_size}
_WHAT = {"reentry": "grid.intervals", "robust_reentry": "grid.intervals x robust.substeps",
         "ocp": "transcription.intervals x steps per interval x (states + controls)"}


def estimate_mb(kind: str, params: dict) -> float | None:
    """A lower estimate of the job's peak resident memory in MB, or None for a kind without a formula."""
    if kind not in FLOOR_MB:
        return None
    measured = FLOOR_MB[kind]
    if kind in _SIZES:
        measured += PER_UNIT_MB[kind] * max(_SIZES[kind](params) - FLOOR_SIZE[kind], 0.0)
    return MARGIN * measured


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
    size = f" (it grows with {_WHAT[kind]})" if kind in _WHAT else ""
    raise OverMemoryCap(f"this {kind} job needs about {need:.0f} MB of memory{size}, more than the cap of {cap} MB "
                        "per job (TRAJLAB_JOB_MEMORY_MB)")
