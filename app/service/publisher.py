"""The API's publisher: job messages go to the broker from a thread of their own, never from a request.

A submission stores its job (the jobs table is the truth), hands it to :meth:`Publisher.send` and answers
at once; this thread sends the message (app.service.broker.publish_job).  When the broker does not answer,
the process's breaker opens (app.service.breaker) and the publisher

* keeps the job, and every one handed to it while the breaker is open, in memory, marking them
  unpublished in the jobs table (``published_at`` NULL, one UPDATE per batch), so that the recovery loop
  of any process that reaches Redis may send them too, and a restart of this one loses nothing;
* sends them as soon as the breaker's probe finds Redis again (a broker that answers but refuses the write,
  ``maxmemory`` or ``MISCONF``, is not a lost one: the jobs are kept the same way and tried again every
  probe interval, without opening the breaker, so ``/readyz`` names the refusal), and marks them published
  (``published_at`` set), skipping those another process sent meanwhile or that are no longer queued.

A job sent twice (here and by a recovery loop) is harmless: the delivery that comes second is dropped at
its claim (app.service.jobs.claim).  At most ``MAX_KEPT`` unpublished jobs are kept in memory; older ones
are left to the recovery loop, which finds them by their empty ``published_at``.
"""
from __future__ import annotations

import logging
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass

from sqlalchemy import select

from app.runtime.db import Database
from app.runtime.models import Job
from app.runtime.settings import Settings
from app.service import breaker as breakers
from app.service import jobs
from app.service.broker import publish_job

log = logging.getLogger("trajlab.api")
MAX_KEPT = 10_000
IDLE_EXIT_S = 30.0  # the thread ends after this long with nothing to send (and starts on the next send)


@dataclass
class _Pending:
    job_id: str
    attempt: int
    kind: str
    queue: str
    marked: bool = False  # published_at set to NULL in the table


class Publisher:
    """One per API app: ``send`` queues messages; a thread publishes them (module docstring)."""

    def __init__(self, db: Database, celery, settings: Settings):
        self.db, self.celery, self.settings = db, celery, settings
        self._pending: OrderedDict[str, _Pending] = OrderedDict()
        self._cv = threading.Condition()
        self._thread: threading.Thread | None = None
        self._breaker: breakers.BrokerBreaker | None = None
        self._refused_until = 0.0  # time.monotonic() before which a broker that refused is not asked again

    @property
    def breaker(self) -> breakers.BrokerBreaker:
        if self._breaker is None:  # per process: an app made before a fork gets its child's breaker
            self._breaker = breakers.for_process(self.settings)
            self._breaker.on_close(self._wake)
        return self._breaker

    def send(self, jobs_to_send) -> None:
        """Publish these committed jobs (objects with ``id``, ``attempts``, ``kind``, ``queue``) soon."""
        with self._cv:
            for job in jobs_to_send:
                self._pending[job.id] = _Pending(job.id, job.attempts, job.kind, job.queue)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._run, name="trajlab-publisher", daemon=True)
                self._thread.start()
            self._cv.notify()

    def pending(self) -> int:
        with self._cv:
            return len(self._pending)

    def _wake(self) -> None:
        with self._cv:
            self._cv.notify()

    def _run(self) -> None:
        while True:
            with self._cv:
                if not self._pending and not self._cv.wait_for(lambda: bool(self._pending), timeout=IDLE_EXIT_S):
                    self._thread = None
                    return
                batch = list(self._pending.values())
            try:
                if self.breaker.open or time.monotonic() < self._refused_until:
                    self._mark_unpublished(batch)
                    self.breaker.wait_closed(self.settings.broker_probe_interval_s)
                    continue
                self._publish(batch)
            except Exception:  # the database (marks) failed too: try again shortly, nothing is dropped
                log.warning("publisher: a pass failed; retrying", exc_info=True)
                self.breaker.wait_closed(self.settings.broker_probe_interval_s)

    def _publish(self, batch: list[_Pending]) -> None:
        marked = [p for p in batch if p.marked]
        if marked:  # kept during an outage: only those still queued and still unpublished (none sent them)
            with self.db.read() as s:
                due = set(s.scalars(select(Job.id).where(Job.id.in_([p.job_id for p in marked]),
                                                         Job.status == "queued", Job.published_at.is_(None))))
            batch = [p for p in batch if not p.marked or p.job_id in due]
            self._forget([p for p in marked if p.job_id not in due])
        sent: list[_Pending] = []
        for p in batch:
            try:
                publish_job(self.celery, self.settings, job_id=p.job_id, attempt=p.attempt, kind=p.kind,
                            queue=p.queue)
            except Exception as exc:
                log.warning("could not publish job %s (%s); kept until the broker takes it", p.job_id,
                            breakers.describe(exc))
                if breakers.unreachable(exc):
                    self.breaker.trip(exc)
                else:  # answered but refused (maxmemory, MISCONF): not a lost broker; try again shortly
                    self._refused_until = time.monotonic() + self.settings.broker_probe_interval_s
                break
            sent.append(p)
        jobs.mark_published(self.db, [p.job_id for p in sent if p.marked])
        self._forget(sent)
        if sent and any(p.marked for p in sent):
            log.warning("published %d job(s) kept while the broker was unreachable",
                        sum(p.marked for p in sent))

    def _mark_unpublished(self, batch: list[_Pending]) -> None:
        fresh = [p for p in batch if not p.marked]
        if fresh:
            jobs.mark_unpublished_many(self.db, [p.job_id for p in fresh])
            for p in fresh:
                p.marked = True
        with self._cv:
            while len(self._pending) > MAX_KEPT:  # the oldest are marked: the recovery loop sends them
                self._pending.popitem(last=False)

    def _forget(self, done: list[_Pending]) -> None:
        with self._cv:
            for p in done:
                if self._pending.get(p.job_id) is p:
                    del self._pending[p.job_id]
