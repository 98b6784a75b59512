"""What the machine gives a worker: its memory, for the default per-job memory cap.

``TRAJLAB_JOB_MEMORY_MB`` defaults to :func:`default_job_memory_mb`: the memory this process may use
(the smaller of ``MemTotal`` and the memory limit of the cgroup it runs in, v2 or v1) times
:data:`MARGIN`, divided among the solver processes one worker runs at once.  The margin leaves room
for the Celery parents, the API, Redis and PostgreSQL on a single machine.  The default is read on
the machine that reads the settings: where the API and the workers run on different hosts, set the
cap explicitly on both, so the up-front check and the worker's guard agree.
"""
from __future__ import annotations

from pathlib import Path

MARGIN = 0.75
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


def default_job_memory_mb(processes: int) -> int:
    """The default cap per job: :data:`MARGIN` of the machine's memory per solver process (0: no cap,
    where the machine's memory is unknown)."""
    memory = machine_memory_mb()
    if memory is None:
        return 0
    return max(int(memory * MARGIN / max(processes, 1)), 1)
