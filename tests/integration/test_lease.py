"""The recovery lease (app.service.lease) on SQLite and PostgreSQL: one holder at a time among
concurrent candidates, renewal, takeover once it expires, release, and the heartbeat's age."""
from __future__ import annotations

import threading
import time
import uuid

import pytest

from app.runtime.db import Database
from app.runtime.migrate import upgrade
from app.service import lease

pytestmark = pytest.mark.integration


@pytest.fixture(params=["sqlite", "postgresql"])
def dbs(request, tmp_path):
    """Three Database objects on one fresh database: three processes' worth of engines."""
    url = f"sqlite:///{tmp_path / 'lease.db'}" if request.param == "sqlite" else request.getfixturevalue("pg_url")
    upgrade(url)
    made = [Database(url) for _ in range(3)]
    yield made
    for db in made:
        db.dispose()


@pytest.fixture
def name():
    """A lease of the test's own: the PostgreSQL database is the session's, where the workers of the suite's
    live services are candidates for the real ``recovery`` lease and would take it over between two steps."""
    return f"test-{uuid.uuid4().hex[:16]}"


def test_one_holder_among_concurrent_candidates(dbs, name):
    state = lease.state(dbs[0], name)
    assert state.holder is None and state.renewed_age_s is None and state.expired
    won: list[str] = []
    start = threading.Barrier(6)

    def candidate(i: int) -> None:
        start.wait()
        if lease.acquire(dbs[i % 3], name, f"c{i}", length_s=30):
            won.append(f"c{i}")
    threads = [threading.Thread(target=candidate, args=(i,)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(won) == 1, won
    holder = won[0]
    # the holder renews; nobody else takes it while it is fresh
    assert lease.acquire(dbs[1], name, holder, length_s=30)
    assert not any(lease.acquire(dbs[2], name, f"other{i}", length_s=30) for i in range(3))
    state = lease.state(dbs[0], name)
    assert state.holder == holder and not state.expired and 0 <= state.renewed_age_s < 5


def test_taken_over_once_expired_and_given_up_on_release(dbs, name):
    # 2 s: long enough that b's try comes inside a's lease on a loaded machine
    assert lease.acquire(dbs[0], name, "a", length_s=2.0)
    assert not lease.acquire(dbs[1], name, "b", length_s=2.0)
    time.sleep(2.3)  # a stopped renewing (died)
    assert lease.state(dbs[2], name).expired
    assert lease.acquire(dbs[1], name, "b", length_s=30)
    assert not lease.acquire(dbs[0], name, "a", length_s=30)  # a, back, has lost it
    assert lease.state(dbs[2], name).holder == "b"
    lease.release(dbs[1], name, "b")  # a clean stop: no wait for the expiry
    assert lease.acquire(dbs[0], name, "a", length_s=30)


def test_a_name_without_a_row_is_made_on_first_take(dbs, name):
    assert lease.acquire(dbs[0], name, "a", length_s=30)
    assert not lease.acquire(dbs[1], name, "b", length_s=30)


def test_recovery_loops_pass_only_while_they_hold_the_lease(tmp_path, redis_url):
    """Two recovery loops (two processes' worth) on one database: one passes, the other waits; when the
    holder stops cleanly the other takes over within a renewal period."""
    from app.runtime.settings import Settings
    from app.service.recovery import Recovery

    url = f"sqlite:///{tmp_path / 'loops.db'}"
    upgrade(url)
    settings = Settings(database_url=url, broker_url=redis_url, reaper_interval_s=0.2, recovery_lease_s=1.5)

    class Counting(Recovery):
        passes = 0

        def tick(self) -> dict:
            self.passes += 1
            return {}

    loops = [Counting(settings, Database(url)) for _ in range(2)]
    threads = [loop.start_thread() for loop in loops]
    try:
        deadline = time.monotonic() + 10
        while sum(loop.holding for loop in loops) != 1:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(1.5)
        holder, other = loops if loops[0].holding else loops[::-1]
        assert holder.passes >= 3 and other.passes == 0 and not other.holding
        assert lease.state(holder.db, lease.RECOVERY).holder == holder.holder
        holder.stop()  # a clean stop gives the lease up
        threads[loops.index(holder)].join(timeout=10)
        stopped = time.monotonic()
        while not other.holding:
            assert time.monotonic() - stopped < 2, "the other loop did not take the lease over"
            time.sleep(0.02)
        passes = other.passes
        time.sleep(0.6)
        assert other.passes > passes
    finally:
        for loop in loops:
            loop.stop()
        for thread in threads:
            thread.join(timeout=10)
        for loop in loops:
            loop.db.dispose()
