"""The default per-job memory cap (app.runtime.resources): every solver process of the host holding a job
at its cap, past it by the guard's overshoot, and an earlier job's leftovers, all at once, fit in the
machine's memory beside the reserve, and nothing much is left unused."""
from __future__ import annotations

import pytest

from app.runtime import resources
from app.runtime.resources import OVERSHOOT, job_memory_mb, reserve_mb
from app.runtime.settings import Settings


def _worst_case(cap: int, processes: int, recycle: int) -> float:
    """Memory the jobs of a host can hold at once: each process at its cap plus overshoot, plus leftovers."""
    return processes * (cap * (1 + OVERSHOOT) + recycle)


def test_the_figures_the_readme_quotes():
    assert reserve_mb(24105) == 3013
    assert job_memory_mb(memory_mb=24105, processes=2) == 6803
    assert job_memory_mb(memory_mb=24105, processes=3) == 4535
    assert reserve_mb(4096) == 1024   # the floor on a small host


@pytest.mark.parametrize("memory_mb", [2048, 8192, 24105, 65536, 515_000])
@pytest.mark.parametrize("processes", [1, 2, 3, 8, 32])
@pytest.mark.parametrize("recycle", [None, 0, 300])
def test_every_process_at_its_cap_fits_beside_the_reserve(memory_mb, processes, recycle):
    cap = job_memory_mb(memory_mb=memory_mb, processes=processes, recycle_mb=recycle)
    left_behind = cap // 2 if recycle is None else recycle   # Settings: recycle unset is half the cap
    room = memory_mb - reserve_mb(memory_mb)
    if cap == 1:  # no room for any job beside the leftovers: the least cap, not a negative one
        assert room / processes < left_behind + 2
        return
    assert _worst_case(cap, processes, left_behind) <= room
    # and the cap is the largest that fits: one MB more would not (int() rounds down)
    assert _worst_case(cap + 1, processes, left_behind + (1 if recycle is None else 0)) > room - processes


def test_an_explicit_reserve_and_recycle_bound_are_used():
    assert job_memory_mb(memory_mb=10_000, processes=2, reserve=2000, recycle_mb=1000) == int((4000 - 1000) / 1.05)
    assert job_memory_mb(memory_mb=1000, processes=4, reserve=2000) == 1   # nothing left: the least cap


def test_settings_derive_the_cap_from_this_machine_and_the_pools():
    memory = resources.machine_memory_mb()
    if memory is None:
        pytest.skip("needs Linux /proc/meminfo")
    one_worker = Settings(database_url="sqlite://", worker_concurrency=2, quick_concurrency=1)
    assert one_worker.job_memory_mb == job_memory_mb(memory_mb=memory, processes=3)
    assert one_worker.worker_recycle_mb == one_worker.job_memory_mb // 2
    host = Settings(database_url="sqlite://", job_processes=6, memory_reserve_mb=500, worker_recycle_mb=100)
    assert host.job_memory_mb == job_memory_mb(memory_mb=memory, processes=6, reserve=500, recycle_mb=100)
    assert Settings(database_url="sqlite://", job_memory_mb=0).job_memory_mb == 0   # no cap, as before
