"""What the machine gives a worker: its memory, for the default per-job memory cap.

``TRAJLAB_JOB_MEMORY_MB`` defaults to :func:`job_memory_mb`, chosen so that every job the host may run at
once can hold its whole cap together with the others and the rest of the stack::

    cap = (M - R) / (N x (1 + OVERSHOOT + RECYCLE_SHARE))

* ``M``: the memory this process may use, the smaller of ``MemTotal`` and the limit of its cgroup (v2 or v1);
* ``R`` (``TRAJLAB_MEMORY_RESERVE_MB``): what runs beside the jobs, PostgreSQL, Redis, the API processes, the
  Celery parents, the watchers, the kernel and its page cache: :data:`RESERVE_SHARE` of ``M``, at least
  :data:`RESERVE_MIN_MB`;
* ``N`` (``TRAJLAB_JOB_PROCESSES``): the solver processes of every pool on the host, each running one job or
  one Monte Carlo chunk or piece at a time: ``TRAJLAB_WORKER_CONCURRENCY + TRAJLAB_QUICK_CONCURRENCY``
  for one ``trajlab worker``; set it where a host runs more (docker-compose.yml: 3);
* per process, a job may hold its cap, pass it by up to :data:`OVERSHOOT` before its guard stops it
  (``worker.watch``), and sit on what earlier jobs left, which ``TRAJLAB_WORKER_RECYCLE_MB`` bounds (half
  the cap unset: :data:`RECYCLE_SHARE`; set, the recycle bound is taken off each process's share instead).

On 24 GB with one heavy and one quick process (24,105 MB, R = 3,013): 6,803 MB per job, where 3/4 of the
memory over the processes gave 9,039 (two jobs and their leftovers could then reach 28 GB).  The default
is read on the machine that reads the settings: where the API and the workers run on different hosts,
set the cap explicitly on both, so the up-front check and the worker's guard agree.
"""
from __future__ import annotations

from pathlib import Path

RESERVE_SHARE = 0.125     # of the machine's memory, for everything but the jobs
RESERVE_MIN_MB = 1024     # the floor of R on a small host: PostgreSQL, Redis, the API and the Celery parents
OVERSHOOT = 0.05          # the guard stops a job within 5% past its cap (worker.watch)
RECYCLE_SHARE = 0.5       # TRAJLAB_WORKER_RECYCLE_MB's default, as a share of the cap
_CGROUP_LIMITS = ("/sys/fs/cgroup/memory.max",                        # v2 (the process's own cgroup mounted)
                  "/sys/fs/cgroup/memory/memory.limit_in_bytes")      # v1


def machine_memory_mb() -> int | None:
    """Memory available to this process in MB, or None where it cannot be read (not Linux)."""
    total = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                total = int(line.split()[1]) // 1024
                break
    except (OSError, ValueError):
        return None
    for path in _CGROUP_LIMITS:
        try:
            text = Path(path).read_text().strip()
        except OSError:
            continue
        if text.isdigit():  # "max" (v2) or a huge number (v1) means no limit
            limit = int(text) // (1024 * 1024)
            if total is None or limit < total:
                total = limit
        break
    return total


def reserve_mb(memory_mb: int) -> int:
    """``R``: the default memory kept for everything but the jobs."""
    return max(int(memory_mb * RESERVE_SHARE), RESERVE_MIN_MB)


def job_memory_mb(*, memory_mb: int, processes: int, reserve: int | None = None,
                  recycle_mb: int | None = None) -> int:
    """The cap per job (module docstring): ``memory_mb`` shared by ``processes`` solver processes after
    ``reserve`` (None: :func:`reserve_mb`), each holding its cap, the guard's overshoot and an earlier
    job's leftovers (``recycle_mb``; None: :data:`RECYCLE_SHARE` of the cap).  At least 1 MB."""
    per_process = (memory_mb - (reserve_mb(memory_mb) if reserve is None else reserve)) / max(processes, 1)
    if recycle_mb is None:
        cap = per_process / (1 + OVERSHOOT + RECYCLE_SHARE)
    else:
        cap = (per_process - recycle_mb) / (1 + OVERSHOOT)
    return max(int(cap), 1)


def default_job_memory_mb(*, processes: int, reserve: int | None = None, recycle_mb: int | None = None) -> int:
    """:func:`job_memory_mb` of this machine's memory (0: no cap, where the machine's memory is unknown)."""
    memory = machine_memory_mb()
    if memory is None:
        return 0
    return job_memory_mb(memory_mb=memory, processes=processes, reserve=reserve, recycle_mb=recycle_mb)
