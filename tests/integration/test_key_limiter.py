"""The failed-key limit across real API processes (issue 36 item 3): two ``trajlab api`` processes (uvicorn,
one process each, free ports on 127.0.0.1) against the real PostgreSQL and the real Redis, each test with a
Redis database of its own.

* The processes share one count per address (it lives in Redis): failures spread over both reach the limit
  on both, where per-process counters would have let each allow the full limit.
* A valid key is served from an address past the limit, on either process.
* An ``X-Forwarded-For`` from 127.0.0.1 is believed only when 127.0.0.1 is in ``TRAJLAB_TRUSTED_PROXIES``:
  by default (uvicorn alone trusts 127.0.0.1) a client choosing a fresh address per request is still limited;
  the same requests to a process told to trust 127.0.0.1 are counted under the forwarded address (the
  control that shows the header reaches the app).
"""
from __future__ import annotations

import os
import subprocess
import sys
from contextlib import ExitStack, contextmanager

import httpx
import pytest

from app.api import auth
from app.api.key_attempts import REDIS_KEY
from app.runtime.db import get_database
from app.runtime.migrate import upgrade
from tests.integration.conftest import REDIS_URL, ROOT, claim_redis_db
from tests.integration.live import free_port, stop_group
from tests.support import wait_serving

pytestmark = pytest.mark.integration

LIMIT = 4
BAD = {"Authorization": "Bearer tl_" + "x" * 43}   # well-formed, so it is looked up and fails


@pytest.fixture()
def redis_db():
    r, url = claim_redis_db(REDIS_URL)
    yield r, url
    r.flushdb()   # also releases the run lock


@pytest.fixture(scope="module")
def keyed_db(pg_url):
    upgrade(pg_url)
    db = get_database(pg_url)
    _, key = auth.create_key(db, name="limiter-user")
    yield pg_url, key
    db.dispose()


@contextmanager
def api_process(pg_url: str, redis_url: str, tmp_path, **env):
    """``trajlab api`` (one uvicorn process) on a free port; its base URL once it answers."""
    port = free_port()
    environ = {**os.environ, "PYTHONPATH": str(ROOT), "TRAJLAB_DATABASE_URL": pg_url, "TRAJLAB_BROKER_URL": redis_url,
               "TRAJLAB_AUTH": "required", "TRAJLAB_API_WORKERS": "1", "TRAJLAB_AUTH_MAX_FAILURES": str(LIMIT),
               "TRAJLAB_AUTH_FAILURE_WINDOW_S": "600", **env}
    with open(tmp_path / f"api-{port}.log", "wb") as log:   # the child keeps its own descriptor
        proc = subprocess.Popen([sys.executable, "-m", "app.cli.commands", "api", "--host", "127.0.0.1", "--port",
                                 str(port)], cwd=ROOT, env=environ, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        wait_serving(base + "/healthz", proc=proc, what="trajlab api", log=tmp_path / f"api-{port}.log", status=200)
        yield base
    finally:
        stop_group(proc)


def status(base: str, headers: dict) -> int:
    return httpx.get(base + "/v1/jobs", headers=headers, timeout=30).status_code


def test_two_api_processes_share_the_count_and_a_valid_key_is_served(keyed_db, redis_db, tmp_path):
    pg_url, key = keyed_db
    r, redis_url = redis_db
    with ExitStack() as stack:
        a, b = (stack.enter_context(api_process(pg_url, redis_url, tmp_path)) for _ in range(2))
        # LIMIT failures spread over both processes: each saw only half of them
        assert [status(base, BAD) for base in (a, b, a, b)] == [401] * LIMIT
        assert r.zcard(REDIS_KEY + "127.0.0.1") == LIMIT
        # the next bad key is refused by either process (per-process counts would allow 2 more on each)
        for base in (a, b):
            resp = httpx.get(base + "/v1/jobs", headers=BAD, timeout=30)
            assert resp.status_code == 429 and 1 <= int(resp.headers["Retry-After"]) <= 600, resp.text
        # a valid key from the same address is served by both, and the refusals were not counted
        good = {"Authorization": f"Bearer {key}"}
        assert [status(a, good), status(b, good)] == [200, 200]
        assert r.zcard(REDIS_KEY + "127.0.0.1") == LIMIT
        assert r.ttl(REDIS_KEY + "127.0.0.1") > 0   # the count expires with its window


def test_a_forged_forwarded_for_from_localhost_is_ignored_unless_trusted(keyed_db, redis_db, tmp_path):
    pg_url, key = keyed_db
    r, redis_url = redis_db

    def forged(i: int) -> dict:
        return {**BAD, "X-Forwarded-For": f"198.51.100.{i}"}

    with api_process(pg_url, redis_url, tmp_path) as base:
        codes = [status(base, forged(i)) for i in range(LIMIT + 2)]
        assert codes == [401] * LIMIT + [429, 429]   # a fresh address per request bought nothing
        assert [k.decode() for k in r.scan_iter(REDIS_KEY + "*")] == [REDIS_KEY + "127.0.0.1"]
    r.delete(REDIS_KEY + "127.0.0.1")
    with api_process(pg_url, redis_url, tmp_path, TRAJLAB_TRUSTED_PROXIES="127.0.0.1") as base:
        # the control: with 127.0.0.1 named as a proxy, its header names the client
        assert [status(base, forged(i)) for i in range(LIMIT + 2)] == [401] * (LIMIT + 2)
        assert sorted(k.decode() for k in r.scan_iter(REDIS_KEY + "*")) == sorted(
            REDIS_KEY + f"198.51.100.{i}" for i in range(LIMIT + 2))
        assert status(base, {"Authorization": f"Bearer {key}"}) == 200
