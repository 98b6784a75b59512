"""Test doubles of the service side (never of a solver): a job context without a worker."""
from __future__ import annotations

from app.kinds.base import InProcessContext


class RecordingContext(InProcessContext):
    """:class:`app.kinds.base.InProcessContext` under the name the tests use (job id ``test``)."""

    def __init__(self, stored: dict | None = None, stop_after: int | None = None):
        super().__init__(stored, stop_after, job_id="test")
