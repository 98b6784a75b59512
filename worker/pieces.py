"""A job's pieces of work fanned out over the workers that exist (``JobContext.run_pieces``), as a study's
points are: each piece is a message any worker may take, and the job works through them too.

The job stores the spec in Redis, publishes one ``trajlab.piece`` message per piece on the heavy queue,
then claims and computes pieces itself until none is left unclaimed, and waits for the others' outputs,
looking every ``POLL_S`` with one pipelined read for all pieces (which are done, which are claimed).
A piece is claimed with ``SET NX`` under a lease its computer keeps renewing (a thread, every third of
the lease), so a piece whose worker died is claimed again once its lease runs out, by the job at the
latest; a duplicate is harmless (a piece is a pure function of the spec and its index).  A cancelled job
sets a stop key that the pieces' ``should_stop`` reads, so other workers stop too.  Unlike the Monte Carlo
fan-out (``worker/fanout.py``), a piece may take minutes (a solve), hence the leases.
"""
from __future__ import annotations

import contextlib
import json
import threading
import time
import uuid
from typing import Callable, ContextManager

import redis

from app.kinds import KINDS  # noqa: F401  (the registry imports every kind, which declares its pieces)
from app.kinds.base import PIECES, JobCancelled, piece_name, run_piece
from app.service.broker import QUEUE_HEAVY

KEY_TTL_S = 24 * 3600
LEASE_S = 30.0
STOP_POLL_S = 0.5
POLL_S = 0.2  # the job's wait between two looks at the others' pieces


def _keys(run_id: str) -> dict[str, str]:
    base = f"trajlab:pieces:{run_id}"
    return {"spec": f"{base}:spec", "results": f"{base}:results", "claim": f"{base}:claim", "stop": f"{base}:stop"}


class _Lease:
    """Renews a claim while its piece is computed."""

    def __init__(self, r: redis.Redis, key: str):
        self.r, self.key, self.done = r, key, threading.Event()
        self.thread = threading.Thread(target=self._renew, name=f"lease-{key}", daemon=True)

    def _renew(self) -> None:
        while not self.done.wait(LEASE_S / 3):
            try:
                self.r.pexpire(self.key, int(LEASE_S * 1000))
            except redis.RedisError:  # the lease lapses; the piece may be computed twice, harmlessly
                pass

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.done.set()
        self.thread.join(timeout=5)


def _stop_reader(r: redis.Redis, stop_key: str, also: Callable[[], bool]) -> Callable[[], bool]:
    last = [0.0, False]

    def should_stop() -> bool:
        if also():
            return True
        now = time.monotonic()
        if now - last[0] > STOP_POLL_S:
            last[0] = now
            try:
                last[1] = bool(r.exists(stop_key))
            except redis.RedisError:
                pass
        return bool(last[1])
    return should_stop


def compute_piece(r: redis.Redis, run_id: str, index: int, *, who: str,
                  should_stop: Callable[[], bool] = lambda: False,
                  guarded: Callable[[dict | None], ContextManager] = lambda job: contextlib.nullcontext()) -> bool:
    """Claim and compute one piece; False if it is claimed or done already, or the run is over.
    ``guarded(job)``: the bounds the piece runs under, given the job it belongs to (``run_distributed``'s
    ``job``; the job's own process passes none, its guard is around it already)."""
    keys = _keys(run_id)
    if r.hexists(keys["results"], str(index)):
        return False
    claim = f"{keys['claim']}:{index}"
    if not r.set(claim, who, nx=True, px=int(LEASE_S * 1000)):
        return False
    raw = r.get(keys["spec"])
    if raw is None:   # the run finished or expired
        return False
    run = json.loads(raw)
    fn = PIECES.get(run["name"])
    with _Lease(r, claim), guarded(run.get("job")):
        if fn is None:
            out = {"raised": f"LookupError: no piece named {run['name']} in this worker"}
        else:
            out = run_piece(fn, run["spec"], index, _stop_reader(r, keys["stop"], should_stop))
    r.hset(keys["results"], str(index), json.dumps({"by": who, "output": out}))
    r.expire(keys["results"], KEY_TTL_S)
    return True


def run_distributed(celery, r: redis.Redis, fn, spec: dict, count: int, *, label: str, who: str,
                    should_stop: Callable[[], bool], on_progress: Callable[[float, str], None],
                    job: dict | None = None) -> list[dict]:
    """The pieces' outputs in index order (module docstring); ``{"by"}`` in each says which worker computed it.
    ``job`` (``{"id", "attempt", "ends_at"}``): the job they belong to, whose bounds hold the pieces other
    workers compute (``worker.tasks.piece``)."""
    run_id = uuid.uuid4().hex
    keys = _keys(run_id)
    r.set(keys["spec"], json.dumps({"name": piece_name(fn), "spec": spec, "job": job}), ex=KEY_TTL_S)
    for i in range(count):
        celery.send_task("trajlab.piece", args=[run_id, i], queue=QUEUE_HEAVY)

    claims = [f"{keys['claim']}:{i}" for i in range(count)]

    def look() -> tuple[int, list[int]]:
        """One round trip: how many pieces are done (reported), and which are neither done nor claimed (a
        lease that lapsed included)."""
        pipe = r.pipeline(transaction=False)
        pipe.hkeys(keys["results"])
        if claims:
            pipe.mget(claims)
        done_keys, *held = pipe.execute()
        done = {int(k) for k in done_keys}
        on_progress(len(done) / count, f"{label} {len(done)}/{count} done")
        return len(done), [i for i in range(count) if i not in done and held[0][i] is None]

    try:
        while True:
            if should_stop():
                r.set(keys["stop"], "1", ex=KEY_TTL_S)
                raise JobCancelled(f"cancelled during the {label}s")
            done, free = look()
            if done >= count:
                break
            for i in free:  # claimed with SET NX in compute_piece: another worker may have taken it since
                if compute_piece(r, run_id, i, who=who, should_stop=should_stop):
                    break  # look again: the progress, and what the others took meanwhile
            else:  # the others' pieces, claimed and leased; one whose lease lapses is free at a later look
                time.sleep(POLL_S)
        raw = r.hgetall(keys["results"])
        entries = [json.loads(raw[str(i).encode()]) for i in range(count)]
    finally:
        r.delete(keys["spec"], keys["results"], *[f"{keys['claim']}:{i}" for i in range(count)])
    return [{**e["output"], "by": e["by"]} for e in entries]
