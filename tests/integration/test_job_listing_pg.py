"""The one-query job listing (app.service.jobs.list_jobs_json: the total as a scalar subquery, params as the stored
JSON text) on PostgreSQL, whose ``json`` column gives its text back as written: the same document as before."""
from __future__ import annotations

import uuid

import pytest

from app.runtime.db import Database
from app.runtime.migrate import upgrade
from tests.unit.test_job_json import check_listing

pytestmark = pytest.mark.integration


def test_list_jobs_json_is_what_response_model_wrote_postgresql(pg_url):
    upgrade(pg_url)
    db = Database(pg_url)
    try:
        check_listing(db, owner=f"listing-{uuid.uuid4().hex[:8]}")  # the session's database has other jobs
    finally:
        db.dispose()
