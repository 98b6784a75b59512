"""Every error code a job can be stored with is in the OpenAPI document (issue 36 item 5).

The codes come from one declaration (app.kinds.failures.WHAT). The codes the code can store are read
from the source itself: every ``{"code": "<literal>"}`` and ``JobFailure("<literal>", ...)`` in app/ and
worker/, and every solver outcome through ``outcome_from_status``; a code written anywhere and not
declared (``resource_limit`` was, before) fails here. A code only known at run time is caught by the
store, which keeps the document inside the enum (the last test).
"""
from __future__ import annotations

import ast
from pathlib import Path

from app.api.main import create_app
from app.kinds.base import outcome_from_status
from app.kinds.failures import ADVICE, ERROR_CODES
from app.runtime.settings import Settings
from app.service import job_document, jobs
from solvers.common import Outcome, SolveStatus

ROOT = Path(__file__).resolve().parents[2]


def _stored_code_literals() -> dict[str, list[str]]:
    """``code -> [file:line, ...]`` of every error code written as a literal in app/ and worker/."""
    found: dict[str, list[str]] = {}

    def add(node, value, path):
        if isinstance(value, ast.Constant) and isinstance(value.value, str):
            found.setdefault(value.value, []).append(f"{path.relative_to(ROOT)}:{node.lineno}")

    for package in ("app", "worker"):
        for path in (ROOT / package).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Dict):
                    for key, value in zip(node.keys, node.values):
                        if isinstance(key, ast.Constant) and key.value == "code":
                            add(node, value, path)
                elif isinstance(node, ast.Call):
                    name = getattr(node.func, "id", None) or getattr(node.func, "attr", None)
                    if name == "JobFailure" and node.args:
                        add(node, node.args[0], path)
    return found


def test_the_openapi_enum_is_the_declared_codes():
    doc = create_app(Settings(database_url="sqlite://", broker_url="redis://127.0.0.1:1/0")).openapi()
    code = doc["components"]["schemas"]["JobError"]["properties"]["code"]
    assert code["enum"] == list(ERROR_CODES)
    assert "resource_limit" in code["enum"]
    assert set(ADVICE) == set(ERROR_CODES)


def test_every_code_the_source_can_store_is_declared():
    found = _stored_code_literals()
    # the scan sees the places it should (a scan that finds nothing would pass vacuously)
    assert {"resource_limit", "time_limit", "worker_lost", "cancelled", "invalid_input", "internal"} <= set(found)
    undeclared = {code: where for code, where in found.items() if code not in ERROR_CODES}
    assert not undeclared, f"error codes stored but not declared in app.kinds.failures.WHAT: {undeclared}"


def test_every_solver_outcome_maps_onto_a_declared_code():
    for outcome in Outcome:
        run = outcome_from_status(SolveStatus(outcome=outcome, solver_status="x", message="m"), None)
        if outcome in (Outcome.OPTIMAL, Outcome.OPTIMALITY_NOT_VERIFIED):     # served as a success
            assert run.error is None and run.status == "succeeded"
        else:
            assert run.error["code"] in ERROR_CODES, outcome


def test_an_undeclared_code_is_stored_as_internal_naming_it(sqlite_db):
    job, _ = jobs.create_job(sqlite_db, kind="intercept", params={}, label=None, preset=None)
    assert jobs.claim(sqlite_db, job.id, 1, worker="w", max_attempts=3, stale_after_s=60)
    assert jobs.finish(sqlite_db, job.id, 1, status="failed", result=None, message="m",
                       error={"code": "no_such_code", "message": "m", "details": {"a": 1}})
    stored = job_document.job_to_dict(jobs.get_job(sqlite_db, job.id))["error"]
    assert stored["code"] == "internal"
    assert stored["details"] == {"a": 1, "undeclared_code": "no_such_code"}
