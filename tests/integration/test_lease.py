"""The recovery lease (app.service.lease) on SQLite and PostgreSQL: one holder at a time among
concurrent candidates, renewal, takeover once it expires, release, and the heartbeat's age."""
from __future__ import annotations

import threading
import time

import pytest
from sqlalchemy import update

from app.runtime.db import Database
from app.runtime.migrate import upgrade
from app.runtime.models import Lease, utcnow
from app.service import lease

pytestmark = pytest.mark.integration


@pytest.fixture(params=["sqlite", "postgresql"])
def dbs(request, tmp_path):
    """Three Database objects on one fresh database: three processes' worth of engines."""
    url = f"sqlite:///{tmp_path / 'lease.db'}" if request.param == "sqlite" else request.getfixturevalue("pg_url")
    upgrade(url)
    made = [Database(url) for _ in range(3)]
    # a fresh row per test (the PostgreSQL database is the session's)
    with made[0].write() as s:
        s.execute(update(Lease).values(holder=None, renewed_at=None, expires_at=utcnow().replace(year=1970)))
    yield made
    for db in made:
        db.dispose()


def test_one_holder_among_concurrent_candidates(dbs):
    state = lease.state(dbs[0], lease.RECOVERY)
    assert state.holder is None and state.renewed_age_s is None and state.expired
    won: list[str] = []
    start = threading.Barrier(6)

    def candidate(i: int) -> None:
        start.wait()
        if lease.acquire(dbs[i % 3], lease.RECOVERY, f"c{i}", length_s=30):
            won.append(f"c{i}")
    threads = [threading.Thread(target=candidate, args=(i,)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(won) == 1, won
    holder = won[0]
    # the holder renews; nobody else takes it while it is fresh
    assert lease.acquire(dbs[1], lease.RECOVERY, holder, length_s=30)
    assert not any(lease.acquire(dbs[2], lease.RECOVERY, f"other{i}", length_s=30) for i in range(3))
    state = lease.state(dbs[0], lease.RECOVERY)
    assert state.holder == holder and not state.expired and 0 <= state.renewed_age_s < 5


def test_taken_over_once_expired_and_given_up_on_release(dbs):
    assert lease.acquire(dbs[0], lease.RECOVERY, "a", length_s=0.5)
    assert not lease.acquire(dbs[1], lease.RECOVERY, "b", length_s=0.5)
    time.sleep(0.7)  # a stopped renewing (died)
    assert lease.state(dbs[2], lease.RECOVERY).expired
    assert lease.acquire(dbs[1], lease.RECOVERY, "b", length_s=30)
    assert not lease.acquire(dbs[0], lease.RECOVERY, "a", length_s=30)  # a, back, has lost it
    assert lease.state(dbs[2], lease.RECOVERY).holder == "b"
    lease.release(dbs[1], lease.RECOVERY, "b")  # a clean stop: no wait for the expiry
    assert lease.acquire(dbs[0], lease.RECOVERY, "a", length_s=30)


def test_a_name_without_a_row_is_made_on_first_take(dbs):
    assert lease.acquire(dbs[0], "other-duty", "a", length_s=30)
    assert not lease.acquire(dbs[1], "other-duty", "b", length_s=30)
