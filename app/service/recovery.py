"""The recovery loop: the jobs table is the truth, and this loop makes the broker agree with it.

Every ``reaper_interval_s`` it

* re-queues running jobs whose heartbeat went stale (their worker died) with a
  new attempt token, or fails them with ``worker_lost`` after ``max_attempts``;
* re-publishes every queued job whose message is not in the broker: jobs whose
  submission found the broker down (``published_at`` NULL), and jobs whose
  message was lost (a Redis restart without persistence, an API process that
  died between commit and publish).  On Redis it looks into the queues and the
  unacknowledged set, so a job waiting its turn in a long backlog is not sent
  twice; duplicates would be harmless anyway (the attempt token);
* moves trade studies on whose points ended without the worker's hook;
* applies ``TRAJLAB_RETENTION_DAYS`` (app.service.retention), at most every ``retention_interval_s``.

It runs outside the job queues, so a backlog never delays recovery, and it survives database and
broker outages by logging and trying again at the next tick.  It must not hang on one process, so it
runs in many: a thread in every Celery worker's main process (worker.celery_app), in ``trajlab
serve``, and in any ``trajlab recover``, and a lease in the database (app.service.lease) says which of
them does the work.  The holder renews the lease every third of ``recovery_lease_s`` (that renewal is
the recovery heartbeat ``/readyz`` reads) and passes every ``reaper_interval_s``; the others try to
take it as often, and one of them does once it has gone unrenewed for ``recovery_lease_s`` (its holder
died, or was cut from the database).  A clean stop gives the lease up at once.  Should two ever pass
at once (a holder that stalls past its lease), nothing breaks: every transition is conditional on the
row's state and a duplicate message is dropped at claim.
"""
from __future__ import annotations

import logging
import re
import threading
import time

from app.service import jobs, lease, metrics, retention, studies
from app.service.broker import QUEUES, create_publisher, publish_job, redis_client
from app.runtime.db import Database, get_database
from app.runtime.settings import Settings

log = logging.getLogger("trajlab.recovery")
_JOB_ID = re.compile(rb"[0-9a-f]{32}")
# kombu's Redis transport keeps delivered, unacknowledged messages in this hash, and their delivery
# times in this sorted set
_UNACKED = "unacked"
_UNACKED_INDEX = "unacked_index"


def publish_or_defer(db: Database, celery, settings: Settings, job) -> bool:
    """Publish a committed job's message; if the broker cannot take it, mark the job unpublished so
    the recovery loop sends it once the broker is back (the row is the truth)."""
    try:
        publish_job(celery, settings, job_id=job.id, attempt=job.attempts, kind=job.kind, queue=job.queue)
        return True
    except Exception:
        log.warning("could not publish job %s (broker unreachable?)", job.id, exc_info=True)
        jobs.mark_unpublished(db, job.id)
        return False


def job_ids_in_broker(r, *, delivered_within_s: float) -> set[str]:
    """Job ids of every message waiting in our queues, or delivered within ``delivered_within_s``
    and not yet acknowledged.  A message delivered longer ago whose job is still queued sits with a
    worker that died before it started it (a SIGKILL): Redis would give it back only after the
    visibility timeout (longer than the longest job), so it counts as lost."""
    found: set[str] = set()
    for queue in QUEUES:
        for raw in r.lrange(queue, 0, -1):
            found.update(m.decode() for m in _JOB_ID.findall(raw))
    recent = r.zrangebyscore(_UNACKED_INDEX, time.time() - delivered_within_s, "+inf")
    if recent:
        for raw in r.hmget(_UNACKED, recent):
            if raw is not None:
                found.update(m.decode() for m in _JOB_ID.findall(raw))
    return found


class LeaseLost(Exception):
    """Another process holds the recovery lease now: this pass stops where it is."""


class Recovery:
    """One recovery pass at a time; ``run_forever`` passes while it holds the lease, until ``stop``."""

    def __init__(self, settings: Settings, db: Database | None = None):
        self.settings = settings
        self.db = db or get_database(settings.database_url, settings)
        self.celery = create_publisher(settings)
        self.redis = redis_client(settings.broker_url, settings=settings)
        self.retention = retention.Retention(settings)
        self.holder = lease.holder_id()
        self.holding = False
        self._renewed = 0.0  # time.monotonic() of the last renewal
        self._stop = threading.Event()

    def _renew(self) -> bool:
        """Take or renew the lease; whether this process holds it now."""
        was = self.holding
        self.holding = False  # until the database says so
        self.holding = lease.acquire(self.db, lease.RECOVERY, self.holder, length_s=self.settings.recovery_lease_s)
        self._renewed = time.monotonic()
        if self.holding != was:
            log.warning("recovery lease %s by %s", "taken" if self.holding else "lost", self.holder)
        return self.holding

    def _keep_lease(self) -> None:
        """Inside a long pass: renew when a third of the lease has gone (a no-op outside run_forever)."""
        due = self.holding and time.monotonic() - self._renewed >= self.settings.recovery_lease_s / 3
        if due and not self._renew():
            raise LeaseLost()

    def _publish(self, job) -> bool:
        return publish_or_defer(self.db, self.celery, self.settings, job)

    def tick(self) -> dict:
        """One pass; the counts of what it did."""
        s = self.settings
        done = {"requeued": 0, "republished": 0, "study_points": 0}
        for job in jobs.reap_stale(self.db, stale_after_s=s.stale_after_s, max_attempts=s.max_attempts):
            if self._publish(job):
                done["requeued"] += 1
                log.warning("re-queued job %s (attempt %d) after its heartbeat went stale", job.id, job.attempts)
        candidates = jobs.publish_candidates(self.db, older_than_s=s.republish_after_s)
        if candidates:
            present = job_ids_in_broker(self.redis, delivered_within_s=s.republish_after_s)
            sent, found = [], []
            for job in candidates:  # thousands after a long broker outage: the lease is kept meanwhile
                self._keep_lease()
                if job.id in present:
                    if job.published_at is None:
                        # in the broker though its sender saw a timeout (the reply was lost, the command not)
                        found.append(job.id)
                    continue
                if not self._publish(job):
                    break  # the broker refuses (down, or full): the rest wait for the next pass
                sent.append(job.id)
            jobs.mark_published(self.db, sent + found)
            if sent:
                done["republished"] = len(sent)
                log.warning("re-published %d queued job(s) missing from the broker", len(sent))
        done["study_points"] = sum(self._publish(job) for job in studies.advance_all(self.db))
        purged = self.retention.run_if_due(self.db)
        if purged is not None:
            done["purged_jobs"], done["purged_studies"] = purged["jobs"], purged["studies"]
        # the process's metrics client: the buffer batches consecutive writes of one client, so the pass's
        # counts go in one batch with the jobs' of a process that also runs jobs (trajlab serve)
        r = metrics.client(self.settings.broker_url)
        metrics.count(r, "reaped", done["requeued"])
        metrics.count(r, "republished", done["republished"])
        metrics.beat(r)  # a complete pass: trajlab_recovery_heartbeat_timestamp_seconds
        return done

    def run_forever(self) -> None:
        s = self.settings
        log.info("recovery candidate %s: a pass every %.1f s while it holds the lease (%.0f s)", self.holder,
                 s.reaper_interval_s, s.recovery_lease_s)
        last_pass = float("-inf")
        try:
            while not self._stop.is_set():
                try:
                    if self._renew() and time.monotonic() - last_pass >= s.reaper_interval_s:
                        last_pass = time.monotonic()  # before the pass: a failing one waits its interval too
                        self.tick()
                except LeaseLost:
                    pass
                except Exception as exc:  # a database or broker outage: try again next time
                    log.warning("recovery pass failed (%s); retrying in %.0f s", type(exc).__name__,
                                s.reaper_interval_s)
                self._stop.wait(min(s.reaper_interval_s, s.recovery_lease_s / 3))
        finally:
            self._release()

    def _release(self) -> None:
        if self.holding:
            self.holding = False
            try:
                lease.release(self.db, lease.RECOVERY, self.holder)
                log.info("recovery lease given up by %s", self.holder)
            except Exception as exc:  # it expires by itself
                log.warning("recovery lease not given up (%s); it expires in %.0f s", type(exc).__name__,
                            self.settings.recovery_lease_s)

    def start_thread(self) -> threading.Thread:
        thread = threading.Thread(target=self.run_forever, name="trajlab-recovery", daemon=True)
        thread.start()
        return thread

    def stop(self) -> None:
        self._stop.set()

