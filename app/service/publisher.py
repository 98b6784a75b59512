"""The API's publisher: job messages go to the broker from a thread of their own, never from a request.

A submission stores its job (the jobs table is the truth), hands it to :meth:`Publisher.send` and answers
at once; this thread sends the message (app.service.broker.publish_job).  When the broker does not answer,
the process's breaker opens (app.service.breaker) and the publisher

* keeps the job, and every one handed to it while the breaker is open, in memory, marking them
  unpublished in the jobs table (``published_at`` NULL, one UPDATE per batch), so that the recovery loop
  of any process that reaches Redis may send them too, and a restart of this one loses nothing;
* sends them as soon as the breaker's probe finds Redis again, and marks them published (``published_at``
  set), skipping those another process sent meanwhile or that are no longer queued.

A broker that answers but refuses the write (``maxmemory``, ``MISCONF``, ``READONLY``) is not a lost one:
the breaker stays closed (``/readyz`` names the refusal) and the jobs are kept the same way, tried again
after one probe interval, then two, four, ... up to ``MAX_BACKOFF`` intervals (:func:`retry_delay_s`); a
pass that the database fails (the marks) waits the same way.  Before the backoff the thread spun between
attempts: 17 refused ``LPUSH`` in 2 s at a 0.1 s interval, and a job whose ``published_at`` mark failed was
pushed again at once, 242 copies in 2 s (tests/integration/test_publisher_refusals.py).  A job in the
broker whose mark failed is never pushed again: only the mark is retried.

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
# The longest wait between attempts, in probe intervals: a refusal lasts until an operator frees memory or
# fixes the dump, so a retry every 8 s (default interval) costs nothing, and the recovery loop sends the
# unpublished jobs meanwhile as well.
MAX_BACKOFF = 8


def retry_delay_s(interval_s: float, failures: int) -> float:
    """The wait after the ``failures``-th failed pass in a row (1, 2, ...): 1, 2, 4, ... intervals, capped."""
    return interval_s * min(2 ** (failures - 1), MAX_BACKOFF)


@dataclass
class _Pending:
    job_id: str
    attempt: int
    kind: str
    queue: str
    marked: bool = False  # published_at set to NULL in the table
    sent: bool = False  # in the broker: only its published_at mark is owed (never pushed twice)


class Publisher:
    """One per API app: ``send`` queues messages; a thread publishes them (module docstring)."""

    def __init__(self, db: Database, celery, settings: Settings):
        self.db, self.celery, self.settings = db, celery, settings
        self._pending: OrderedDict[str, _Pending] = OrderedDict()
        self._arrived: list[_Pending] = []  # handed over while the thread waits to try again: marked at once
        self._cv = threading.Condition()
        self._thread: threading.Thread | None = None
        self._breaker: breakers.BrokerBreaker | None = None
        self._retry_at = 0.0  # time.monotonic() before which the thread does not try again (module docstring)
        self._failures = 0  # failed passes in a row

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
                p = self._pending[job.id] = _Pending(job.id, job.attempts, job.kind, job.queue)
                self._arrived.append(p)
            if not self._pending:  # nothing handed over and nothing kept (a study's GET with no new point)
                return
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._run, name="trajlab-publisher", daemon=True)
                self._thread.start()
            self._cv.notify()

    def pending(self) -> int:
        with self._cv:
            return len(self._pending)

    def _wake(self) -> None:
        """The breaker closed: try again now, whatever the backoff said."""
        with self._cv:
            self._retry_at, self._failures = 0.0, 0
            self._cv.notify()

    def _next(self) -> tuple[list[_Pending], bool] | None:
        """What to send, and whether its retry time has come (False: jobs handed over during the wait, to be
        marked unpublished now and sent with the others); None after ``IDLE_EXIT_S`` with nothing to send."""
        with self._cv:
            while True:
                if not self._pending and not self._cv.wait_for(lambda: bool(self._pending), timeout=IDLE_EXIT_S):
                    self._thread = None
                    return None
                wait = self._retry_at - time.monotonic()
                arrived, self._arrived = self._arrived, []
                if wait <= 0:
                    return list(self._pending.values()), True
                if arrived:
                    return arrived, False
                self._cv.wait(wait)  # a send does not end the wait (it is marked, above); the breaker's close does

    def _pause(self, *, failed: bool) -> None:
        """Wait before the next pass: a probe interval while the breaker is open (its close wakes us), the
        backoff after a failed pass."""
        interval = self.settings.broker_probe_interval_s
        with self._cv:
            if failed:
                self._failures += 1
            self._retry_at = time.monotonic() + (retry_delay_s(interval, self._failures) if failed else interval)

    def _run(self) -> None:
        while (got := self._next()) is not None:
            batch, due = got
            try:
                if not due:
                    self._mark_unpublished(batch)
                elif self.breaker.open:  # asked every pass: it keeps the breaker's monitor running
                    self._mark_unpublished(batch)
                    self._pause(failed=False)
                elif self._publish(batch):
                    with self._cv:
                        self._failures = 0
                else:
                    self._mark_unpublished(batch)
                    self._pause(failed=True)
            except Exception:  # the database (marks) failed too: try again later, nothing is dropped
                log.warning("publisher: a pass failed; retrying", exc_info=True)
                self._pause(failed=True)

    def _publish(self, batch: list[_Pending]) -> bool:
        """Send the batch in order and mark what was kept published; False if the broker did not take one
        (the rest wait)."""
        marked = [p for p in batch if p.marked and not p.sent]
        if marked:  # kept during an outage: only those still queued and still unpublished (none sent them)
            with self.db.read() as s:
                due = set(s.scalars(select(Job.id).where(Job.id.in_([p.job_id for p in marked]),
                                                         Job.status == "queued", Job.published_at.is_(None))))
            batch = [p for p in batch if p.sent or not p.marked or p.job_id in due]
            self._forget([p for p in marked if p.job_id not in due])
        taken = True
        for p in batch:
            if p.sent:
                continue
            try:
                publish_job(self.celery, self.settings, job_id=p.job_id, attempt=p.attempt, kind=p.kind,
                            queue=p.queue)
            except Exception as exc:
                log.warning("could not publish job %s (%s); kept until the broker takes it", p.job_id,
                            breakers.describe(exc))
                if breakers.unreachable(exc):
                    self.breaker.trip(exc)  # a refusal (maxmemory, MISCONF) is not a lost broker: backoff only
                taken = False
                break
            p.sent = True
        sent = [p for p in batch if p.sent]
        jobs.mark_published(self.db, [p.job_id for p in sent if p.marked])
        self._forget(sent)
        if sent and any(p.marked for p in sent):
            log.warning("published %d job(s) kept while the broker was unreachable",
                        sum(p.marked for p in sent))
        return taken

    def _mark_unpublished(self, batch: list[_Pending]) -> None:
        fresh = [p for p in batch if not p.marked and not p.sent]
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
