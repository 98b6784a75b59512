"""The API's publisher against a Redis that answers but refuses writes (``maxmemory`` reached under
noeviction: ``OOM``), on a redis-server of the test's own (the limit is a server setting; the shared Redis
is never reconfigured), and a database that refuses the ``published_at`` mark (a trigger of the test's own).

The breaker stays closed through both (Redis answers a PING), so nothing but the publisher's own backoff
spaces its attempts: Redis's command statistics count the ``LPUSH`` attempts (taken and rejected), the
process's CPU time shows whether the thread spins, and the queue's length whether a message went twice.
"""
from __future__ import annotations

import time

import pytest
import redis
from sqlalchemy import text

from app.runtime.settings import Settings
from app.service import jobs
from app.service import publisher as publisher_module
from app.service.broker import QUEUE_JOBS, create_publisher
from app.service.publisher import Publisher
from tests.faults.servers import RedisServer
from tests.support import until

pytestmark = pytest.mark.integration
WINDOW_S = 2.0  # refusals watched this long
INTERVAL_S = 0.1  # TRAJLAB_BROKER_PROBE_INTERVAL_S here: the first retry's delay
# A spinning thread burns up to the window's whole second per second (0.63 s of 2.0 s measured before the
# backoff, on this 2-core machine under a test run); a backing-off one a few milliseconds per attempt, and
# the breaker's PINGs as much (about 20 ms in the window).  A tenth of the window lies between the two.
SPIN_CPU_SHARE = 0.1



@pytest.fixture
def own_redis(tmp_path):
    server = RedisServer(tmp_path).start()
    yield server
    server.kill()


def _lpush_attempts(r: redis.Redis) -> int:
    """LPUSHes Redis received since the last CONFIG RESETSTAT, taken or rejected (OOM)."""
    stats = r.info("commandstats").get("cmdstat_lpush", {})
    return int(stats.get("calls", 0)) + int(stats.get("rejected_calls", 0))


def _attempts_bound(window_s: float) -> int:
    """The most attempts the publisher's backoff allows within ``window_s``: the first at the window's start,
    then one after each delay of :func:`app.service.publisher.retry_delay_s` (1, 2, 4, ... intervals, capped)."""
    n, elapsed = 1, 0.0
    while (elapsed := elapsed + publisher_module.retry_delay_s(INTERVAL_S, n)) <= window_s:
        n += 1
    return n


def _setup(sqlite_db, server: RedisServer):
    settings = Settings(database_url="sqlite://", broker_url=server.url, broker_probe_interval_s=INTERVAL_S,
                        broker_probe_timeout_s=0.5)
    r = redis.Redis.from_url(server.url)
    # below what Redis held at its start, with no data: every write is refused while it is set
    r.config_set("maxmemory", str(r.info("memory")["used_memory_startup"]))
    publisher = Publisher(sqlite_db, create_publisher(settings), settings)
    job = jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None)[0]
    publisher.send([job])
    until(lambda: _lpush_attempts(r) >= 1 and jobs.get_job(sqlite_db, job.id).published_at is None,
           "the refused job marked unpublished")
    assert r.llen(QUEUE_JOBS) == 0
    return r, publisher, job


def test_refused_writes_are_retried_with_a_bounded_backoff_not_a_spin(sqlite_db, own_redis):
    r, publisher, job = _setup(sqlite_db, own_redis)
    r.config_resetstat()
    cpu, start = time.process_time(), time.monotonic()
    time.sleep(WINDOW_S)
    cpu, window = time.process_time() - cpu, time.monotonic() - start
    attempts = _lpush_attempts(r)
    # before: a retry every probe interval (20 in the window) and the thread spinning between them
    assert 1 <= attempts <= _attempts_bound(window), attempts
    assert cpu < SPIN_CPU_SHARE * window, cpu
    assert not publisher.breaker.open  # Redis answered throughout: only the backoff spaced the attempts
    r.config_set("maxmemory", "0")  # the limit raised: sent within the longest delay
    until(lambda: publisher.pending() == 0, "the kept job published after the limit was raised")
    assert jobs.get_job(sqlite_db, job.id).published_at is not None
    assert r.llen(QUEUE_JOBS) == 1


def test_a_job_sent_but_not_marked_published_is_not_sent_again(sqlite_db, own_redis):
    r, publisher, job = _setup(sqlite_db, own_redis)
    with sqlite_db.write() as s:  # the database refuses the mark (as a full disk or a lost primary would)
        s.execute(text("CREATE TRIGGER refuse_published BEFORE UPDATE OF published_at ON jobs "
                       "WHEN NEW.published_at IS NOT NULL BEGIN SELECT RAISE(ABORT, 'refused by the test'); END"))
    r.config_set("maxmemory", "0")
    until(lambda: r.llen(QUEUE_JOBS) >= 1, "the job sent once the limit was raised")
    r.config_resetstat()
    cpu, start = time.process_time(), time.monotonic()
    time.sleep(WINDOW_S)
    cpu, window = time.process_time() - cpu, time.monotonic() - start
    # before: the failed mark sent the job again at once, over and over (thousands of copies in the window)
    assert r.llen(QUEUE_JOBS) == 1 and _lpush_attempts(r) == 0
    assert cpu < SPIN_CPU_SHARE * window, cpu
    assert publisher.pending() == 1 and jobs.get_job(sqlite_db, job.id).published_at is None
    with sqlite_db.write() as s:
        s.execute(text("DROP TRIGGER refuse_published"))
    until(lambda: publisher.pending() == 0, "the mark written once the database takes it")
    assert jobs.get_job(sqlite_db, job.id).published_at is not None
    assert r.llen(QUEUE_JOBS) == 1
