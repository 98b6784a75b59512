"""A broker that falls silent (tests/silent_link.py: a relay to the real Redis that holds what is sent while
cut and delivers it late, as a dead link's retransmissions do), without root: the breaker opens and callers
skip Redis; the API's publisher keeps what it could not send and publishes it, ``published_at`` set, when
Redis answers; a batch of metrics sent again after a lost reply is counted once.  The namespaced
end-to-end test is tests/faults/test_silent_broker_loss.py."""
from __future__ import annotations

import json
import time

import pytest
import redis

from app.api.key_attempts import SharedKeyAttempts
from app.runtime.settings import Settings
from app.service import breaker, jobs, metrics, metrics_buffer
from app.service.broker import QUEUE_JOBS, create_publisher, redis_client
from app.service.publisher import Publisher
from tests.silent_link import SilentLink
from tests.support import until

pytestmark = pytest.mark.integration
BOUND_S = 30  # every wait below is for a state; this only ends a test that would otherwise hang



@pytest.fixture
def link(redis_url):
    # a Redis database of this test's own: the run's database is shared with the workers other modules of
    # the same pytest(-xdist) process started, and one of them took the published message off the queue
    # before this test could see it there (failed in the full suite, never alone)
    from tests.integration.conftest import claim_redis_db

    own, url = claim_redis_db(redis_url)
    host, port = url.split("//", 1)[1].split("/", 1)[0].split(":")
    relay = SilentLink(host, int(port))
    yield relay, url.rsplit("/", 1)[1]
    relay.close()
    own.flushdb()  # also releases its run lock


def _settings(url: str) -> Settings:
    return Settings(database_url="sqlite://", broker_url=url, broker_probe_interval_s=0.2,
                    broker_probe_timeout_s=0.3, redis_socket_timeout_s=1.5, redis_connect_timeout_s=1.0)


def _queued_ids(r: redis.Redis) -> list[str]:
    return [json.loads(json.loads(m)["headers"]["argsrepr"].replace("'", '"'))[0] for m in r.lrange(QUEUE_JOBS, 0, -1)]


def test_the_publisher_keeps_jobs_through_a_silent_cut_and_publishes_them_after(sqlite_db, link):
    relay, db_index = link
    settings = _settings(relay.url(db_index))
    direct = redis.Redis.from_url(settings.broker_url.replace(f":{relay.port}/", ":6379/"))
    direct.delete(QUEUE_JOBS)
    publisher = Publisher(sqlite_db, create_publisher(settings), settings)

    def new_job():
        return jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None)[0]

    first = new_job()
    publisher.send([first])
    until(lambda: _queued_ids(direct) == [first.id], "the first job published")
    relay.cut()
    kept = [new_job(), new_job()]
    publisher.send(kept[:1])
    until(lambda: publisher.breaker.open, "the breaker opened")
    publisher.send(kept[1:])
    until(lambda: all(jobs.get_job(sqlite_db, j.id).published_at is None for j in kept), "kept jobs marked")
    assert publisher.pending() == 2
    touched: list[int] = []
    assert publisher.breaker.call(lambda: touched.append(1), "skipped") == "skipped" and not touched
    relay.restore()
    until(lambda: publisher.pending() == 0, "kept jobs published after the return")
    assert all(jobs.get_job(sqlite_db, j.id).published_at is not None for j in kept)
    # a publish that timed out during the cut may have reached Redis late as well: never a job missing
    assert set(_queued_ids(direct)) == {first.id, *(j.id for j in kept)}
    direct.delete(QUEUE_JOBS)


def test_metrics_sent_again_after_a_lost_reply_count_once(link):
    relay, db_index = link
    settings = _settings(relay.url(db_index))
    direct = redis.Redis.from_url(settings.broker_url.replace(f":{relay.port}/", ":6379/"))
    key = metrics.PREFIX + "job_duration_seconds"
    direct.delete(key)
    client = redis_client(settings.broker_url, settings=settings)
    relay.cut()
    metrics.record_job(client, kind="silent", duration_s=1.0)
    # the first attempt times out, and its request waits in the relay; so do the retries
    time.sleep(metrics_buffer.RETRY_S + settings.redis_socket_timeout_s)
    assert direct.hget(key, "silent|count") is None
    relay.restore()
    assert metrics_buffer.flush(BOUND_S)
    time.sleep(0.5)  # late copies of the first attempt, if any, reach Redis (the relay delivers them at once)
    assert int(direct.hget(key, "silent|count")) == 1 and float(direct.hget(key, "silent|sum")) == 1.0
    direct.delete(key)


def test_the_failed_key_limit_counts_in_the_process_while_the_breaker_is_open(link):
    relay, db_index = link
    settings = _settings(relay.url(db_index))
    b = breaker.for_process(settings)
    client = redis_client(settings.broker_url, settings=settings, socket_timeout=0.5)
    limiter = SharedKeyAttempts(client, max_failures=2, window_s=60, breaker=b)
    relay.cut()
    limiter.failed("10.0.0.1")  # finds Redis silent: opens the breaker, counted here
    assert b.open
    limiter.failed("10.0.0.1")  # does not ask Redis: the breaker is open
    assert limiter.retry_after_s("10.0.0.1") is not None
    relay.restore()
    until(lambda: not b.open, "the breaker closed after the return")


def test_the_metrics_script_applies_metric_writes_only(redis_url):
    # the buffer's server-side script is constant and applies only the allow-listed counter updates: a
    # command outside the list is refused before the buffer takes it and, sent to the script anyway,
    # refused by it before anything (the batch's token included) is written
    with pytest.raises(ValueError, match="not a metric write"):
        metrics_buffer.add(object(), [("FLUSHDB",)])
    r = redis.Redis.from_url(redis_url)
    token, key = metrics_buffer.TOKEN_PREFIX + "allow-list-test", "trajlab:test:allow-list"
    r.delete(token, key)
    with pytest.raises(redis.ResponseError, match="not allowed"):
        r.eval(metrics_buffer._APPLY_ONCE, 1, token, 60, 4, "HINCRBY", key, "n", 1, 2, "DEL", key)
    assert not r.exists(token) and not r.exists(key)
    assert r.eval(metrics_buffer._APPLY_ONCE, 1, token, 60, 4, "HINCRBY", key, "n", 1) == 1
    assert r.eval(metrics_buffer._APPLY_ONCE, 1, token, 60, 4, "HINCRBY", key, "n", 1) == 0   # applied once
    assert r.hget(key, "n") == b"1"
    r.delete(token, key)
