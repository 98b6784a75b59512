"""Celery application factory: broker, reliability settings, beat schedule.

The database is the truth; Celery only delivers ``(job_id, attempt)`` messages,
so no result backend is configured.
"""
from __future__ import annotations

from celery import Celery

from app.settings import Settings, get_settings


def create_celery(settings: Settings | None = None) -> Celery:
    settings = settings or get_settings()
    app = Celery("trajlab", broker=settings.broker_url, include=["worker.tasks"])
    app.conf.update(
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
        task_ignore_result=True,
        task_serializer="json",
        accept_content=["json"],
        broker_connection_retry_on_startup=True,
        worker_send_task_events=False,
        # Jobs run in prefork children; recycle them now and then to bound memory
        # growth of long-lived numerical processes (CasADi caches, heyoka JIT).
        worker_max_tasks_per_child=200,
        beat_schedule={
            "reap-stale-jobs": {"task": "trajlab.reap", "schedule": settings.reaper_interval_s},
        },
        timezone="UTC",
    )
    return app


celery_app = create_celery()


def publish_job(app: Celery, settings: Settings, *, job_id: str, attempt: int, kind: str) -> None:
    """Send the delivery message for ``attempt`` of a committed job, with its kind's time limits."""
    soft = settings.time_limit_s(kind)
    app.send_task("trajlab.run_job", args=[job_id, attempt],
                  soft_time_limit=soft, time_limit=soft + settings.hard_time_limit_margin_s)
