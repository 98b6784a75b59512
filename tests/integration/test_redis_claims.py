"""A test run's Redis database is given back when the run ends, and lapses when it is killed.

A killed run once left fifteen four-hour locks and the next run could claim no database.
"""
from __future__ import annotations

import subprocess
import sys

import pytest
import redis

from tests.integration.conftest import REDIS_URL, ROOT, RUN_LOCK_KEY, RUN_LOCK_TTL_S

pytestmark = pytest.mark.integration

CLAIM = ("import sys, time; from tests.integration.conftest import claim_redis_db; "
         "r, url = claim_redis_db(sys.argv[1]); print(url, flush=True); "
         "time.sleep(float(sys.argv[2]))")


def _claim_in_child(hold_s: float) -> tuple[subprocess.Popen, str]:
    child = subprocess.Popen([sys.executable, "-c", CLAIM, REDIS_URL, str(hold_s)], cwd=ROOT,
                             stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None
    url = child.stdout.readline().strip()
    assert url.startswith("redis://"), url
    return child, url


def test_a_finished_run_gives_its_database_back():
    child, url = _claim_in_child(0.0)
    assert child.wait(timeout=60) == 0
    assert redis.Redis.from_url(url).get(RUN_LOCK_KEY) is None


def test_a_killed_runs_claim_lapses_within_its_ttl():
    child, url = _claim_in_child(600.0)
    r = redis.Redis.from_url(url)
    try:
        assert r.get(RUN_LOCK_KEY) is not None
        assert 0 < r.ttl(RUN_LOCK_KEY) <= RUN_LOCK_TTL_S
    finally:
        child.kill()
        child.wait(timeout=60)
    # SIGKILL runs no exit handler: the claim stays, but never longer than its TTL (not four hours)
    assert 0 < r.ttl(RUN_LOCK_KEY) <= RUN_LOCK_TTL_S
    r.delete(RUN_LOCK_KEY)
