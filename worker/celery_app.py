"""Celery application factory for the worker: shared broker settings plus the tasks.

The database is the truth; Celery only delivers ``(job_id, attempt)`` messages,
so no result backend is configured.  The settings themselves live in
``app.service.broker`` so the API's producer and this consumer cannot drift apart.
Recovery (the reaper, the re-publisher, retention) is not a task: it runs in
``app.service.recovery``'s own loop, outside the job queues, in a thread of this worker's main
process under the recovery lease (worker.recovery_duty).  A Redis that refuses writes (``maxmemory``,
``MISCONF``) does not stop the worker (worker.broker_guard).
"""
from __future__ import annotations

import signal

from celery import Celery, signals

from app.runtime import logs
from app.service import metrics
from app.service.broker import celery_config
from app.runtime.settings import Settings, get_settings
from worker import broker_guard, broker_watch, guard, recovery_duty  # noqa: F401  (broker_watch, recovery_duty: their signal receivers)


def create_celery(settings: Settings | None = None) -> Celery:
    settings = settings or get_settings()
    app = Celery("trajlab", broker=settings.broker_url, include=["worker.tasks"])
    app.conf.update(
        celery_config(settings),
        # Jobs run in prefork children; recycle them now and then to bound memory
        # growth of long-lived numerical processes (CasADi caches, heyoka JIT).
        worker_max_tasks_per_child=200,
        # ...and at once when a job left more than TRAJLAB_WORKER_RECYCLE_MB behind (KiB; Celery reads the
        # peak, which _after_task resets to what is held now): what earlier jobs leave is not charged to
        # the next one (worker.guard), so this bounds what a process holds besides its current job.
        worker_max_memory_per_child=(settings.worker_recycle_mb or 0) * 1024 or None,
        # A command Redis refuses in the consumer (a queue declaration's SADD while Redis is full) is a
        # reconnect with backoff, as a lost connection is, not an exit (worker.broker_guard covers the
        # acknowledgement, the delivery record and the restore of overdue deliveries).
        broker_channel_error_retry=True,
    )
    broker_guard.install()
    return app


@signals.task_prerun.connect
def _no_soft_limit_exception(**_) -> None:
    # Celery's soft time limit raises SoftTimeLimitExceeded from a signal handler wherever Python happens to
    # be: inside CasADi's IPOPT iteration callback it became IPOPT's NonIpopt_Exception_Thrown and the job
    # failed as internal; inside the result's write it would lose the result.  A job's deadline is kept by
    # its context instead (should_stop at every solver iteration, the same limit: worker.context), by its
    # guard for a job that does not call back (worker.guard), and by the hard limit (worker.tasks.JobTask).
    signal.signal(signal.SIGUSR1, signal.SIG_IGN)


@signals.task_postrun.connect
def _after_task(**_) -> None:
    # in the pool process, before Celery compares its memory with worker_max_memory_per_child
    guard.release_free_memory()
    guard.reset_peak()


celery_app = create_celery()


@signals.worker_ready.connect
def _count_start(**_) -> None:
    # trajlab_worker_restarts_total: a worker that keeps restarting shows as a rate (deploy/prometheus/alerts.yml)
    settings = get_settings()
    metrics.count(metrics.client(settings.broker_url), "worker_restarts")


if get_settings().log_format == "json":
    # Connected, this signal replaces Celery's own logging set-up (its receivers configure instead)
    @signals.setup_logging.connect
    def _json_logging(loglevel=None, **_) -> None:
        logs.configure("json", loglevel or "INFO")
