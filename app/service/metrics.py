"""The service's Prometheus metrics, read on scrape from the database and Redis (docs/operations.md).

Why not prometheus-client's multiprocess mode for these: the jobs' metrics are made by processes that
need not share a machine or a directory with the API that is scraped (Celery workers, their pool
children, the recovery loop), and they outlive processes (a worker restarts, a pool child is recycled
every 200 tasks).  So each API process answers a scrape from shared state, and every process gives the
same answer:

* the jobs table, the truth of the life cycle: jobs submitted and finished by kind (and status),
  running and queued by kind;
* Redis (the broker's database), for what happens to a job in passing: the durations, queue waits
  and solver iterations of finished jobs as histogram buckets, the recovery loop's re-queues and
  re-publications and its heartbeat, worker starts (:func:`record_job`, :func:`count`,
  :func:`beat`, never on an HTTP request's path), and the broker's queue lengths.

Those writes never hold up a job and are not lost when Redis is cut off: they go to a buffer of the process
(app.service.metrics_buffer) that a thread of its own flushes, keeps while Redis does not answer, and
writes once when it answers again (each flush carries a token, so one whose reply was lost is not counted
twice when it is sent again).

The HTTP metrics are the API processes' own (app.api.observability, in the library's multiprocess mode).
"""
from __future__ import annotations

import functools
import logging
import math
import time
from typing import Iterable, Iterator

from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, HistogramMetricFamily
from prometheus_client.registry import Collector
from sqlalchemy import func, select

from app.runtime.db import Database
from app.runtime.models import FINAL_STATUSES, Job
from app.service import metrics_buffer
from app.service.broker import QUEUES, redis_client

log = logging.getLogger("trajlab.metrics")
PREFIX = "trajlab:metrics:"
COUNTERS = PREFIX + "counters"
HEARTBEAT = PREFIX + "recovery_heartbeat"
# Histograms: name -> (help, upper bounds); Redis hash PREFIX + name holds "<kind>|<bound>" counts per bucket
# (not cumulative), "<kind>|sum" and "<kind>|count".
HISTOGRAMS = {
    "job_duration_seconds": ("Run time of finished jobs, claim to stored outcome, by kind",
                             (0.5, 1, 2, 5, 10, 30, 60, 120, 300, 600, 1800, 3600)),
    "job_queue_wait_seconds": ("Time from submission to a worker's first claim, by kind",
                               (0.05, 0.1, 0.25, 0.5, 1, 2, 5, 10, 30, 60, 300, 900, 3600)),
    "solver_iterations": ("Solver iterations of finished jobs (result.solver.iterations), by kind",
                          (5, 10, 20, 50, 100, 200, 500, 1000, 3000, 10000)),
}
# Event counters: Redis field -> (metric name without _total, help)
EVENTS = {
    "reaped": ("jobs_reaped", "Running jobs whose heartbeat went stale, re-queued or failed by the recovery loop"),
    "republished": ("jobs_republished", "Queued jobs re-sent by the recovery loop (missing from the broker)"),
    "worker_restarts": ("worker_restarts", "Celery worker nodes started (the first start included)"),
}


@functools.lru_cache(maxsize=4)
def client(broker_url: str):
    """This process's Redis client for metrics (the broker's database), made on first use and reused by every
    metric write of the process (app.service.metrics_buffer batches consecutive writes of one client)."""
    return redis_client(broker_url)


def _bucket(bounds: Iterable[float], value: float) -> str:
    for bound in bounds:
        if value <= bound:
            return repr(float(bound))
    return "+Inf"


def record_job(redis, *, kind: str, duration_s: float | None = None, queue_wait_s: float | None = None,
               iterations: float | None = None) -> None:
    """Add one job's observations (those given) to the histograms (buffered: module docstring)."""
    commands = []
    for name, value in (("job_duration_seconds", duration_s), ("job_queue_wait_seconds", queue_wait_s),
                        ("solver_iterations", iterations)):
        if value is None or not math.isfinite(value):
            continue
        key = PREFIX + name
        commands += [("HINCRBY", key, f"{kind}|{_bucket(HISTOGRAMS[name][1], value)}", 1),
                     ("HINCRBYFLOAT", key, f"{kind}|sum", repr(float(value))),
                     ("HINCRBY", key, f"{kind}|count", 1)]
    metrics_buffer.add(redis, commands)


def count(redis, event: str, n: int = 1) -> None:
    """Add ``n`` to an event counter (:data:`EVENTS`)."""
    if n:
        metrics_buffer.add(redis, [("HINCRBY", COUNTERS, event, n)])


def beat(redis) -> None:
    """The recovery loop finished a pass now."""
    metrics_buffer.add(redis, [("SET", HEARTBEAT, repr(time.time()))])


def solver_iterations(result: dict | None) -> float | None:
    """The iterations a kind's result reports (``result["solver"]["iterations"]``), if it does."""
    solver = (result or {}).get("solver") if isinstance(result, dict) else None
    value = solver.get("iterations") if isinstance(solver, dict) else None
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


class ServiceCollector(Collector):
    """Reads the jobs table and Redis on each scrape (``describe`` is empty: nothing is read at
    registration)."""

    def __init__(self, db: Database, redis, kinds: Iterable[str], breaker=None):
        self.db, self.redis, self.kinds = db, redis, tuple(kinds)
        self.breaker = breaker  # app.service.breaker.BrokerBreaker: while open, the broker's families are left out

    def describe(self):
        return []

    def collect(self) -> Iterator:
        yield from self._from_database()
        if self.breaker is None:
            yield from self._from_redis()
            return
        # a scrape never waits on a lost broker: its families are missing until it answers again
        yield from self.breaker.call(lambda: list(self._from_redis()), [], trip=False)

    def _from_database(self) -> Iterator:
        with self.db.read_connection() as conn:
            rows = conn.execute(select(Job.kind, Job.status, func.count()).group_by(Job.kind, Job.status)).all()
        submitted = CounterMetricFamily("trajlab_jobs_submitted", "Jobs submitted, by kind", labels=["kind"])
        finished = CounterMetricFamily("trajlab_jobs_finished", "Jobs finished, by kind and final status",
                                       labels=["kind", "status"])
        running = GaugeMetricFamily("trajlab_jobs_running", "Jobs running now, by kind", labels=["kind"])
        queued = GaugeMetricFamily("trajlab_jobs_queued", "Jobs waiting for a worker, by kind", labels=["kind"])
        per_kind: dict[str, dict[str, int]] = {kind: {} for kind in self.kinds}
        for kind, status, n in rows:
            per_kind.setdefault(kind, {})[status] = int(n)
        for kind, by_status in sorted(per_kind.items()):
            submitted.add_metric([kind], sum(by_status.values()))
            running.add_metric([kind], by_status.get("running", 0))
            queued.add_metric([kind], by_status.get("queued", 0))
            for status in sorted(FINAL_STATUSES):
                finished.add_metric([kind, status], by_status.get(status, 0))
        yield from (submitted, finished, running, queued)

    def _from_redis(self) -> Iterator:
        pipe = self.redis.pipeline(transaction=False)
        pipe.hgetall(COUNTERS)
        pipe.get(HEARTBEAT)
        for queue in QUEUES:
            pipe.llen(queue)
        for name in HISTOGRAMS:
            pipe.hgetall(PREFIX + name)
        pipe.info("memory")
        counters, heartbeat, *rest, memory = pipe.execute()
        depths, histograms = rest[:len(QUEUES)], rest[len(QUEUES):]
        counters = {k.decode(): int(v) for k, v in counters.items()}
        for field, (name, text) in EVENTS.items():
            yield CounterMetricFamily(f"trajlab_{name}", text, value=counters.get(field, 0))
        yield GaugeMetricFamily("trajlab_recovery_heartbeat_timestamp_seconds",
                                "Unix time of the recovery loop's last complete pass (0: none yet)",
                                value=float(heartbeat) if heartbeat else 0.0)
        depth = GaugeMetricFamily("trajlab_queue_depth", "Messages waiting in the broker, by queue", labels=["queue"])
        for queue, n in zip(QUEUES, depths):
            depth.add_metric([queue], n)
        yield depth
        # a broker that runs out of memory refuses writes (every submission then fails): alert before
        yield GaugeMetricFamily("trajlab_broker_memory_used_bytes", "Memory the broker (Redis) uses",
                                value=float(memory.get("used_memory", 0)))
        yield GaugeMetricFamily("trajlab_broker_maxmemory_bytes", "The broker's maxmemory (0: no limit)",
                                value=float(memory.get("maxmemory", 0)))
        for (name, (text, bounds)), raw in zip(HISTOGRAMS.items(), histograms):
            yield self._histogram(name, text, bounds, {k.decode(): float(v) for k, v in raw.items()})

    def _histogram(self, name: str, text: str, bounds, fields: dict[str, float]) -> HistogramMetricFamily:
        family = HistogramMetricFamily(f"trajlab_{name}", text, labels=["kind"])
        kinds = sorted(set(self.kinds) | {f.split("|", 1)[0] for f in fields})
        for kind in kinds:
            cumulative, buckets = 0.0, []
            for bound in [*map(float, bounds), math.inf]:
                label = "+Inf" if bound == math.inf else repr(bound)
                cumulative += fields.get(f"{kind}|{label}", 0.0)
                buckets.append((label, cumulative))
            family.add_metric([kind], buckets, sum_value=fields.get(f"{kind}|sum", 0.0))
        return family
