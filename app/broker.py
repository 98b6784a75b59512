"""The broker side the API and the worker share: Celery settings, queue names, publishing.

The API publishes job messages but never imports ``worker/`` (the layering rule
checked in CI): it builds a producer-only Celery app from :func:`celery_config`,
and the worker's ``create_celery`` builds its consuming app from the same
function, so both sides agree on serializer, transport options and queues.
The jobs table is the truth; a message only carries ``(job_id, attempt)``.
"""
from __future__ import annotations

from celery import Celery

from app.settings import Settings, get_settings

# Quick jobs and heavy jobs (robust reentry, large midcourse runs, Monte Carlo
# chunks) wait in separate queues so a heavy backlog never holds a quick job back.
QUEUE_JOBS = "trajlab.jobs"
QUEUE_HEAVY = "trajlab.heavy"
QUEUES = (QUEUE_JOBS, QUEUE_HEAVY)


def celery_config(settings: Settings) -> dict:
    """Celery settings with the reason for each; shared by producer and worker."""
    return dict(
        # A job's message is acknowledged only when the task returns, so a worker
        # that dies mid-solve leaves the message to be delivered again...
        task_acks_late=True,
        # ...including when the pool child is killed (SIGKILL, OOM killer).
        task_reject_on_worker_lost=True,
        # Solves take seconds to minutes: a worker must not hoard queued jobs that
        # an idle worker could start now.
        worker_prefetch_multiplier=1,
        # Redis re-delivers an unacknowledged message after the visibility timeout;
        # it must exceed the longest hard time limit or a long solve would run twice.
        broker_transport_options={"visibility_timeout": int(settings.longest_hard_time_limit_s + 600)},
        task_default_queue=QUEUE_JOBS,
        task_ignore_result=True,
        task_serializer="json",
        accept_content=["json"],
        broker_connection_retry_on_startup=True,
        worker_send_task_events=False,
        timezone="UTC",
    )


def create_publisher(settings: Settings | None = None) -> Celery:
    """A producer-only Celery app (no tasks imported) for the API and the re-publisher."""
    settings = settings or get_settings()
    app = Celery("trajlab", broker=settings.broker_url)
    app.conf.update(celery_config(settings))
    return app


def redis_client(broker_url: str, *, socket_timeout: float = 5.0):
    """A redis-py client for the broker URL; kombu's ``redis+socket:///path`` is redis-py's unix socket."""
    import redis

    if broker_url.startswith("redis+socket://"):
        return redis.Redis(unix_socket_path=broker_url.removeprefix("redis+socket://"), socket_timeout=socket_timeout)
    return redis.Redis.from_url(broker_url, socket_timeout=socket_timeout)


def publish_job(app: Celery, settings: Settings, *, job_id: str, attempt: int, kind: str,
                queue: str = QUEUE_JOBS) -> None:
    """Send the delivery message for ``attempt`` of a committed job, with its kind's time limits."""
    soft = settings.time_limit_s(kind)
    app.send_task("trajlab.run_job", args=[job_id, attempt], queue=queue,
                  soft_time_limit=soft, time_limit=soft + settings.hard_time_limit_margin_s)
