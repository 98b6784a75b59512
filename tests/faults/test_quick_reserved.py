"""Issue 30: queues that cannot starve.  A worker started for both queues (``trajlab worker``) keeps a
process for quick jobs, so a quick job finishes while every heavy slot is busy and more heavy work waits."""
from __future__ import annotations

import time

import pytest

from tests.faults.conftest import report

pytestmark = [pytest.mark.integration, pytest.mark.faults]

# NSGA-II at the largest population and generation count allowed: 100 times the preset's evaluations, minutes
# on any machine, so it holds its slot while the quick jobs run (it is cancelled at the end); its cost (1e6)
# is above the heavy cost this test sets, so it goes to the heavy queue.  (A reentry solve at 1000 intervals
# was the heavy job until it finished in under 25 s and voided the scenario.)
HEAVY = {"kind": "midcourse", "preset": "upper-stage-two-corrections",
         "params": {"population": 1000, "generations": 5000}}
WAIT_S = 300.0


def _wait(stack, job_id: str, statuses: tuple[str, ...], timeout: float) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        job = stack.client.get(f"/v1/jobs/{job_id}").json()
        if job["status"] in statuses or time.monotonic() > deadline:
            return job
        time.sleep(0.2)


def test_a_quick_job_finishes_while_every_heavy_slot_is_busy(stack):
    stack.settings.heavy_cost = 1000.0  # the API's settings: HEAVY (cost 1e6) is heavy, the quick job is not
    stack.settings.max_active_cost_per_owner = 1e7  # two heavy jobs and the quick ones admitted together
    stack.start_worker(concurrency=1)  # one slot for heavy and quick jobs, one reserved for quick ones
    heavy = []
    for _ in range(2):
        r = stack.submit(HEAVY)
        assert r.status_code == 202, r.text
        heavy.append(r.json()["id"])
    # Waits for states, bounded generously (WAIT_S): what the test asserts is the order of states (the quick
    # jobs done while the heavy slot is still busy), which a slow machine does not change, not a speed.
    assert _wait(stack, heavy[0], ("running",), WAIT_S)["status"] == "running"
    t0 = time.monotonic()
    quick = [stack.submit().json()["id"] for _ in range(3)]
    jobs, _ = stack.wait_final(quick, timeout=WAIT_S)
    during = stack.statuses(heavy)
    report("quick-reserved", quick_succeeded=sum(j["status"] == "succeeded" for j in jobs.values()),
           heavy_states="/".join(during[h]["status"] for h in heavy), quick_done_s=time.monotonic() - t0)
    assert all(jobs[q]["status"] == "succeeded" for q in quick), [jobs[q]["status"] for q in quick]
    # every heavy slot was busy the whole time, and heavy work was still waiting for one
    assert [during[h]["status"] for h in heavy] == ["running", "queued"], during
    for h in heavy:
        stack.client.post(f"/v1/jobs/{h}/cancel")
    assert all(_wait(stack, h, ("cancelled", "failed", "succeeded"), WAIT_S)["status"] == "cancelled" for h in heavy)
