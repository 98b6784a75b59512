"""The broker side the API and the worker share: Celery settings, queue names, publishing.

The API publishes job messages but never imports ``worker/`` (the layering rule
checked in CI): it builds a producer-only Celery app from :func:`celery_config`,
and the worker's ``create_celery`` builds its consuming app from the same
function, so both sides agree on serializer, transport options and queues.
The jobs table is the truth; a message only carries ``(job_id, attempt)``.

Publishing on Redis (every deployment of ours) skips Celery's producer: Celery's
``send_task`` cost about 0.7 ms of CPU per message here (message building, kombu's
retry wrapper, channel bookkeeping), most of an API submission's budget, so
:func:`publish_job` writes the same Celery message (protocol 2, as kombu's Redis
transport stores it: :func:`job_message`) with one ``LPUSH`` on a long-lived
connection pool (about 0.06 ms).  The worker consumes it with plain Celery, and the
recovery loop reads the queues as before (tests/integration/test_broker_publish.py
checks both against Celery's own message).  Other broker URLs go through Celery.
"""
from __future__ import annotations

import base64
import functools
import json
import os
import re
import socket
import threading
import uuid

from celery import Celery

from app.runtime.settings import Settings, get_settings

# Quick jobs and heavy jobs (robust reentry, large midcourse runs, Monte Carlo
# chunks) wait in separate queues so a heavy backlog never holds a quick job back.
QUEUE_JOBS = "trajlab.jobs"
QUEUE_HEAVY = "trajlab.heavy"
QUEUES = (QUEUE_JOBS, QUEUE_HEAVY)


def time_limit_s(settings: Settings, kind: str) -> float:
    """The soft time limit of ``kind``: its override (``TRAJLAB_TIME_LIMIT_<KIND>_S``), else its
    ``KindSpec.time_limit_s``."""
    if kind in settings.time_limits_s:
        return float(settings.time_limits_s[kind])
    from app.kinds import KINDS

    return float(KINDS[kind].time_limit_s)


def longest_hard_time_limit_s(settings: Settings) -> float:
    """The longest hard time limit over the registry (the broker's visibility timeout exceeds it)."""
    from app.kinds import KINDS

    return max(time_limit_s(settings, k) for k in KINDS) + settings.hard_time_limit_margin_s


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
        # The same bounded socket, keepalive and health check as the service's own client
        # (redis_options): without a socket timeout a publish or ack over a dead link waited forever.
        broker_transport_options={"visibility_timeout": int(longest_hard_time_limit_s(settings) + 600),
                                  **redis_options(settings)},
        # Celery's own bound on opening the broker connection (its AMQP-style connect and the retries).
        broker_connection_timeout=settings.redis_connect_timeout_s,
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


def redis_options(settings: Settings) -> dict:
    """redis-py's (and kombu's transport's) bounds on every Redis call: a reply within the socket timeout,
    a connect within the connect timeout, an idle connection pinged before use, TCP keepalive on."""
    return {"socket_timeout": settings.redis_socket_timeout_s,
            "socket_connect_timeout": settings.redis_connect_timeout_s,
            "socket_keepalive": True,
            "health_check_interval": settings.redis_health_check_interval_s}


# The broker URLs that are Redis (kombu's ``redis+socket:///path`` is redis-py's unix socket); any other
# transport goes through Celery.
REDIS_SCHEMES = ("redis://", "rediss://", "redis+socket://")


def redis_client(broker_url: str, *, settings: Settings | None = None, **kwargs):
    """A redis-py client for the broker URL with :func:`redis_options` (``kwargs`` override them)."""
    return _connect(broker_url, {**redis_options(settings or get_settings()), **kwargs})


def _connect(broker_url: str, options: dict):
    import redis

    if broker_url.startswith("redis+socket://"):
        options = {k: v for k, v in options.items() if k != "socket_keepalive"}  # a unix socket has no TCP keepalive
        return redis.Redis(unix_socket_path=broker_url.removeprefix("redis+socket://"), **options)
    return redis.Redis.from_url(broker_url, **options)


@functools.lru_cache(maxsize=8)
def bounded_client(broker_url: str, timeout_s: float):
    """The client of a call that answers within ``timeout_s`` or counts as unanswered (the breaker's PING,
    ``/readyz``'s write, ``/metrics``' reads): one connect and one reply bounded by ``timeout_s``, no retry
    and no idle-connection PING before it (each would add a wait to the bound).  One per process, URL and
    bound (the client's pool is thread-safe and made anew in a forked child)."""
    from redis.backoff import NoBackoff
    from redis.retry import Retry

    return _connect(broker_url, {"socket_timeout": timeout_s, "socket_connect_timeout": timeout_s,
                                 "socket_keepalive": True, "health_check_interval": 0,
                                 "retry": Retry(NoBackoff(), 0)})


def refusal(exc: BaseException) -> str:
    """Redis's own words for a refused command, which carry no address or key: 'OOM command not allowed
    when used memory > 'maxmemory'', 'MISCONF Redis is configured to save RDB snapshots, but it's
    currently unable to persist to disk', 'READONLY You can't write against a read only replica'."""
    # redis-py prefixes an error inside a pipeline with the command, whose arguments are ours: drop it
    text = re.sub(r"^Command # \d+ \(.*\) of pipeline caused error: ", "", str(exc), flags=re.S)
    text = text.split(". ")[0].strip().rstrip(".")[:200]
    code = {"OutOfMemoryError": "OOM", "ReadOnlyError": "READONLY"}.get(type(exc).__name__, "")
    return f"{code} {text}" if code and not text.startswith(code) else text


RUN_JOB_TASK = "trajlab.run_job"
_publishers: dict[str, object] = {}
_publishers_lock = threading.Lock()


def job_message(job_id: str, attempt: int, *, queue: str, soft_time_limit_s: float, time_limit_s: float) -> bytes:
    """The Celery message (protocol 2) of ``trajlab.run_job(job_id, attempt)`` as kombu's Redis transport
    stores it in the queue's list: what ``send_task`` would write, with fresh task id and delivery tag."""
    task_id = str(uuid.uuid4())
    args = [job_id, attempt]
    body = [args, {}, {"callbacks": None, "errbacks": None, "chain": None, "chord": None}]
    return json.dumps({
        "body": base64.b64encode(json.dumps(body).encode()).decode(),
        "content-encoding": "utf-8",
        "content-type": "application/json",
        "headers": {
            "lang": "py", "task": RUN_JOB_TASK, "id": task_id, "shadow": None, "eta": None, "expires": None,
            "group": None, "group_index": None, "retries": 0, "timelimit": [time_limit_s, soft_time_limit_s],
            "root_id": task_id, "parent_id": None, "argsrepr": repr(args), "kwargsrepr": "{}",
            "origin": f"gen{os.getpid()}@{socket.gethostname()}", "ignore_result": None,
            "replaced_task_nesting": 0, "stamped_headers": None, "stamps": {},
        },
        "properties": {
            "correlation_id": task_id, "reply_to": "", "delivery_mode": 2,
            "delivery_info": {"exchange": "", "routing_key": queue}, "priority": 0,
            "body_encoding": "base64", "delivery_tag": str(uuid.uuid4()),
        },
    }).encode()


def _redis_publisher(broker_url: str):
    """One client (its own connection pool, thread-safe, re-made after a fork) per broker URL and process.
    One immediate retry covers a pooled connection that a broker restart closed; a broker that is down
    fails the publish at once (the caller marks the job unpublished), never after a backoff."""
    client = _publishers.get(broker_url)
    if client is None:
        from redis.backoff import NoBackoff
        from redis.retry import Retry

        with _publishers_lock:
            client = _publishers.get(broker_url)
            if client is None:
                client = _publishers[broker_url] = redis_client(broker_url, retry=Retry(NoBackoff(), 1))
    return client


def publish_job(app: Celery, settings: Settings, *, job_id: str, attempt: int, kind: str,
                queue: str = QUEUE_JOBS) -> None:
    """Send the delivery message for ``attempt`` of a committed job, with its kind's time limits.
    Raises if the broker does not take it (the caller keeps the job and marks it unpublished)."""
    soft = time_limit_s(settings, kind)
    hard = soft + settings.hard_time_limit_margin_s
    broker_url = str(app.conf.broker_url or settings.broker_url)
    if broker_url.startswith(REDIS_SCHEMES):
        _redis_publisher(broker_url).lpush(queue, job_message(job_id, attempt, queue=queue, soft_time_limit_s=soft,
                                                              time_limit_s=hard))
        return
    app.send_task(RUN_JOB_TASK, args=[job_id, attempt], queue=queue, soft_time_limit=soft, time_limit=hard)
