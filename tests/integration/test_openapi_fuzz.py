"""Schemathesis against the OpenAPI document: no 5xx, documented status codes honoured.

Runs the app on SQLite with the real Redis as broker (on a database of its own)
and no worker, so fuzzed submissions are stored and queued but never solved.
"""
from __future__ import annotations

import os

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import status_code_conformance

from app.api.main import create_app
from app.runtime.migrate import upgrade
from app.runtime.settings import Settings
from tests.integration.conftest import REDIS_URL, claim_redis_db

pytestmark = pytest.mark.integration

# A Redis database of this run's own (see conftest): a fixed one could be flushed by a concurrent run.
_REDIS, BROKER = claim_redis_db(os.environ.get("TRAJLAB_TEST_FUZZ_REDIS", REDIS_URL))
DB_PATH = f"/tmp/trajlab-fuzz-{os.getpid()}.db"
upgrade(f"sqlite:///{DB_PATH}")
APP = create_app(Settings(database_url=f"sqlite:///{DB_PATH}", broker_url=BROKER))
schema = schemathesis.openapi.from_asgi("/openapi.json", APP)


@pytest.fixture(scope="module", autouse=True)
def _clean_broker():
    yield
    _REDIS.flushdb()
    os.unlink(DB_PATH)


@schema.parametrize()
@settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck))
def test_api_conforms(case):
    # /readyz's 503 is its documented answer here, not a server error: no worker runs, so no process holds the
    # recovery lease and the heartbeat is (rightly) "never ran"; its body must still name the part.
    if case.path == "/readyz":
        response = case.call_and_validate(checks=[status_code_conformance])
        assert response.status_code != 503 or "recovery" in response.text, response.text
        return
    case.call_and_validate(checks=[not_a_server_error, status_code_conformance])
