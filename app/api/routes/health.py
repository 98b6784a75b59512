"""Liveness (/healthz) and readiness (/readyz: database and broker reachable).

The bodies say only "up" or "down" per component: the reasons (addresses,
socket paths, driver messages) go to the log, not to whoever asks.
"""
from __future__ import annotations

import logging

from fastapi import APIRouter
from fastapi.responses import JSONResponse
from sqlalchemy import text

from app.api.deps import CeleryDep, DatabaseDep

router = APIRouter(tags=["health"])
log = logging.getLogger("trajlab.health")


@router.get("/healthz")
def healthz():
    return {"status": "ok"}


@router.get("/readyz", responses={503: {"description": "Database or broker unreachable"}})
def readyz(db: DatabaseDep, celery: CeleryDep):
    checks: dict[str, str] = {}
    try:
        with db.read() as s:
            s.execute(text("SELECT 1"))
        checks["database"] = "up"
    except Exception:
        log.warning("readiness: database unreachable", exc_info=True)
        checks["database"] = "down"
    try:
        with celery.connection_for_write() as conn:
            conn.ensure_connection(max_retries=1, timeout=2)
        checks["broker"] = "up"
    except Exception:
        log.warning("readiness: broker unreachable", exc_info=True)
        checks["broker"] = "down"
    ok = all(v == "up" for v in checks.values())
    return JSONResponse(status_code=200 if ok else 503, content={"status": "ready" if ok else "not ready", **checks})
