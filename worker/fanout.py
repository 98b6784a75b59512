"""Split a Monte Carlo over the workers that exist, without deadlocking the one that asks.

The job's task publishes one ``trajlab.mc_chunk`` message per chunk and then
works through the chunks itself; every chunk is claimed with ``SET NX`` in
Redis, so each is computed once by whoever gets to it first.  With idle workers
the run scales out; with a single busy worker (or concurrency 1) the job still
finishes on its own.  Chunk results are pure functions of (spec, seed, range)
(see ``solvers.uncertainty.montecarlo``), so a chunk whose claimer died is
simply recomputed by the job after a grace period, and a duplicate is harmless.
"""
from __future__ import annotations

import contextlib
import json
import socket
import time
import uuid
from typing import Callable, ContextManager

import redis

from app.service.broker import QUEUE_HEAVY
from app.kinds.base import JobCancelled
from solvers.uncertainty.montecarlo import merge_chunks, simulate_chunk

KEY_TTL_S = 24 * 3600




def _keys(run_id: str) -> tuple[str, str, str]:
    base = f"trajlab:mc:{run_id}"
    return f"{base}:spec", f"{base}:results", f"{base}:claim"


def _job_key(run_id: str) -> str:
    return f"trajlab:mc:{run_id}:job"


def compute_chunk(r: redis.Redis, run_id: str, index: int, start: int, count: int, seed: int, *, who: str,
                  guarded: Callable[[dict | None], ContextManager] = lambda job: contextlib.nullcontext()) -> bool:
    """Claim and compute one chunk; False if someone else already has it.  ``guarded(job)``: the bounds
    the chunk runs under, given the job it belongs to (``run_distributed``'s ``job``; the job's own process
    passes none, its guard is around it already)."""
    spec_key, results_key, claim_key = _keys(run_id)
    if not r.set(f"{claim_key}:{index}", who, nx=True, ex=KEY_TTL_S):
        return False
    raw = r.get(spec_key)
    if raw is None:  # the run finished or expired: nothing to do
        return False
    job = r.get(_job_key(run_id))
    with guarded(None if job is None else json.loads(job)):
        partial = simulate_chunk(json.loads(raw), seed, start, count)
    r.hset(results_key, str(index), json.dumps({"by": who, "partial": partial}))
    r.expire(results_key, KEY_TTL_S)
    return True


def run_distributed(celery, r: redis.Redis, *, spec: dict, samples: int, seed: int, chunk_size: int,
                    should_stop: Callable[[], bool] = lambda: False,
                    on_progress: Callable[[float, str], None] | None = None,
                    grace_s: float = 60.0, job: dict | None = None) -> dict:
    """Run ``samples`` samples in chunks of ``chunk_size`` across workers; merged summary.  ``job``
    (``{"id", "attempt", "ends_at"}``): the job the run belongs to, whose bounds hold the chunks other
    workers compute (``worker.tasks.mc_chunk``)."""
    run_id = uuid.uuid4().hex
    spec_key, results_key, claim_key = _keys(run_id)
    ranges = [(i, a, min(chunk_size, samples - a)) for i, a in enumerate(range(0, samples, chunk_size))]
    if job is not None:  # before the spec: a chunk that finds the spec finds its job
        r.set(_job_key(run_id), json.dumps(job), ex=KEY_TTL_S)
    r.set(spec_key, json.dumps(spec), ex=KEY_TTL_S)
    for i, a, n in ranges:
        celery.send_task("trajlab.mc_chunk", args=[run_id, i, a, n, seed], queue=QUEUE_HEAVY)
    me = f"job@{socket.gethostname()}"
    try:
        for i, a, n in ranges:
            if should_stop():
                raise JobCancelled("Monte Carlo cancelled")
            compute_chunk(r, run_id, i, a, n, seed, who=me)
            if on_progress:
                on_progress(r.hlen(results_key) / len(ranges), f"Monte Carlo chunk {r.hlen(results_key)}/{len(ranges)}")
        deadline = time.monotonic() + grace_s
        while r.hlen(results_key) < len(ranges):
            if should_stop():
                raise JobCancelled("Monte Carlo cancelled")
            if time.monotonic() > deadline:
                # A claimer died: recompute what is missing here (same streams, same numbers).
                done = {int(k) for k in r.hkeys(results_key)}
                for i, a, n in ranges:
                    if i not in done:
                        r.delete(f"{claim_key}:{i}")
                        compute_chunk(r, run_id, i, a, n, seed, who=me)
                break
            time.sleep(0.05)
        raw = r.hgetall(results_key)
        entries = [json.loads(raw[str(i).encode()]) for i, _, _ in ranges]
    finally:
        r.delete(spec_key, results_key, _job_key(run_id), *[f"{claim_key}:{i}" for i, _, _ in ranges])
    summary = merge_chunks([e["partial"] for e in entries])
    by: dict[str, int] = {}
    for e in entries:
        by[e["by"]] = by.get(e["by"], 0) + 1
    summary["distribution"] = {"chunks": len(ranges), "chunk_size": chunk_size, "computed_by": by}
    return summary
