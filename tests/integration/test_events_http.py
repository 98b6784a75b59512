"""Live progress over SSE against a real worker: the events of a whole job in order, and resumption."""
from __future__ import annotations

import time

import pytest

from app.cli.client import parse_sse

pytestmark = pytest.mark.integration

RANK = {"queued": 0, "running": 1, "succeeded": 2, "failed": 2, "cancelled": 2}
FINAL = ("succeeded", "failed", "cancelled")
# NSGA-II reports progress per generation; 1,500 generations run for seconds, hundreds of the
# service's polls, so the test sees the job running on any CPU (it waits for that state, below).
MIDCOURSE = {"mode": "optimize", "corrections": 2, "population": 60, "generations": 1500, "seed": 3}


def _wait_running(client, job_id: str, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = client.get(f"/v1/jobs/{job_id}").json()
        if job["status"] == "running" or job["status"] in FINAL:
            return
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} never started")


def _events(client, job_id: str, headers: dict | None = None, stop_after: int | None = None) -> list[dict]:
    out = []
    with client.stream("GET", f"/v1/jobs/{job_id}/events", headers=headers or {}) as r:
        assert r.status_code == 200 and r.headers["content-type"].startswith("text/event-stream")
        for ev in parse_sse(r.iter_lines()):
            out.append(ev)
            if stop_after is not None and len(out) >= stop_after:
                break
    return out


def test_events_of_a_whole_job_in_order_then_resume_without_repeats(service):
    job = service.submit("midcourse", preset="upper-stage-two-corrections", params=MIDCOURSE).json()
    first = _events(service.client, job["id"], stop_after=1)
    assert first[0]["event"] == "progress" and first[0]["data"]["id"] == job["id"]
    # Reconnect where the first stream stopped, once the job is seen running (a state, not a speed):
    # the rest of the job, no repeat of what was seen.
    _wait_running(service.client, job["id"])
    rest = _events(service.client, job["id"], headers={"Last-Event-ID": first[0]["id"]})
    events = first + rest
    ids = [e["id"] for e in events]
    assert len(ids) == len(set(ids)), ids
    assert events[-1]["event"] == "end" and events[-1]["data"]["status"] == "succeeded"
    assert all(e["event"] == "progress" for e in events[:-1])
    ranks = [RANK[e["data"]["status"]] for e in events]
    assert ranks == sorted(ranks)
    running = [e["data"]["progress"] for e in events if e["data"]["status"] == "running"]
    # the contract: the running state is reported (the resumed stream opened while it held) and
    # its progress never goes back; how many values a stream sees depends on the CPU's speed
    assert running == sorted(running) and len(running) >= 1, events
    assert events[-1]["data"]["progress"] == 1.0
    # A finished job seen to its end: resuming from the final id sends nothing more.
    assert _events(service.client, job["id"], headers={"Last-Event-ID": events[-1]["id"]}) == []
    # Without Last-Event-ID a finished job's stream is its final state, once.
    again = _events(service.client, job["id"])
    assert [e["event"] for e in again] == ["end"] and again[0]["id"] == events[-1]["id"]


def test_events_of_an_unknown_job_is_404(service):
    assert service.client.get("/v1/jobs/doesnotexist/events").status_code == 404
