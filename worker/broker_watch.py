"""A worker notices a silent broker loss within its health-check interval and says so in its log.

Cut from Redis by a silent loss (packets dropped), Celery's consumer waits on its connection and logged
nothing for a minute (issue 36), though the README states a 10 s health check
(``TRAJLAB_REDIS_HEALTH_CHECK_INTERVAL_S``).  In the worker's main process a breaker's monitor
(app.service.breaker) PINGs Redis every third of that interval, each PING bounded by the same third: a
loss is logged ("broker unreachable ...") within two thirds of the interval, and the return ("broker
reachable again after N s") within one third of it.  The jobs go on meanwhile (the jobs table is the
truth), and their metrics wait in the process's buffer (app.service.metrics_buffer), which a pool child
flushes before it exits.
"""
from __future__ import annotations

from celery import signals

from app.runtime.settings import get_settings
from app.service import breaker, metrics_buffer

FLUSH_AT_EXIT_S = 5.0  # a pool child's exit waits this long at most for its metrics to reach Redis


@signals.worker_ready.connect
def watch(**_) -> None:
    settings = get_settings()
    third = settings.redis_health_check_interval_s / 3
    if third > 0:
        breaker.for_process(settings, role="worker", interval_s=third, timeout_s=third).watch()


@signals.worker_process_shutdown.connect
def flush_metrics(**_) -> None:
    metrics_buffer.flush(FLUSH_AT_EXIT_S)
