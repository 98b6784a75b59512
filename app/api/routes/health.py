"""Liveness (/healthz) and readiness (/readyz: the database answers, the broker accepts a write, the
recovery loop's heartbeat is fresh).

Each component is "up" or says what is wrong in words that carry no address, path or driver message
(those go to the log, not to whoever asks):

* ``database``: ``down`` when ``SELECT 1`` fails;
* ``broker``: ``down`` when Redis cannot be reached (at once while the process's breaker holds it
  unreachable, app.service.breaker; else within ``TRAJLAB_BROKER_PROBE_TIMEOUT_S``), ``refuses writes: <Redis's reason>`` when it
  answers but refuses a ``SET`` with a short expiry (``maxmemory`` reached under noeviction, a failed
  dump's ``MISCONF``, a read-only replica): a broker that only opens connections cannot take a job;
* ``recovery``: ``heartbeat stale for N s`` when no process renewed the recovery lease for
  ``recovery_lease_s`` (every worker, ``trajlab serve`` and ``trajlab recover`` are candidates:
  app.service.lease), ``never ran`` when none ever held it.  Without it, jobs of dead workers stay
  running and lost messages are not re-sent;
* ``database_storage`` (SQLite) and ``data_dir`` (embedded mode): ``full: N MB free ...`` when the
  filesystem has less than ``min_free_disk_mb`` left (app.runtime.disk).
"""
from __future__ import annotations

import logging

from fastapi import APIRouter
from fastapi.responses import JSONResponse
from sqlalchemy import text

from app.api.deps import CeleryDep, DatabaseDep, SettingsDep
from app.runtime.disk import storage_checks
from app.runtime.settings import Settings
from app.service import breaker as breakers
from app.service import lease
from app.service.broker import REDIS_SCHEMES, bounded_client, refusal

router = APIRouter(tags=["health"])
log = logging.getLogger("trajlab.health")
READY_KEY = "trajlab:readyz"


@router.get("/healthz")
def healthz():
    return {"status": "ok"}


def _broker(settings: Settings, celery) -> str:
    if not settings.broker_url.startswith(REDIS_SCHEMES):
        with celery.connection_for_write() as conn:
            conn.ensure_connection(max_retries=1, timeout=2)
        return "up"
    from redis.exceptions import ResponseError

    # the process's breaker (app.service.breaker): a broker known unreachable is "down" at once, and a call
    # that finds it so opens the breaker; a readiness check never waits longer than the probe's bound
    breaker = breakers.for_process(settings)
    if breaker.open:
        return "down"  # the breaker logged it
    bound = min(settings.broker_probe_timeout_s, breakers.REQUEST_BOUND_S)
    r = bounded_client(settings.broker_url, bound)
    try:
        if not breaker.call(lambda: r.set(READY_KEY, "1", ex=10), False, trip=False):
            log.warning("readiness: broker did not answer within %.1f s", bound)
            return "down"
    except ResponseError as exc:
        log.warning("readiness: broker refuses writes (%s)", exc)
        return f"refuses writes: {refusal(exc)}"
    return "up"


def _recovery(settings: Settings, db) -> str:
    held = lease.state(db, lease.RECOVERY)
    if held.renewed_age_s is None:
        return "never ran: no worker, trajlab serve or trajlab recover has held the recovery lease"
    if held.renewed_age_s > settings.recovery_lease_s:
        return f"heartbeat stale for {held.renewed_age_s:.0f} s"
    return "up"


@router.get("/readyz", responses={503: {"description": "Database down, broker down or refusing writes, or the "
                                                      "recovery heartbeat stale (the body names which)"}})
def readyz(db: DatabaseDep, celery: CeleryDep, settings: SettingsDep):
    checks: dict[str, str] = {}
    try:
        with db.read() as s:
            s.execute(text("SELECT 1"))
        checks["database"] = "up"
    except Exception:
        log.warning("readiness: database unreachable", exc_info=True)
        checks["database"] = "down"
    try:
        checks["broker"] = _broker(settings, celery)
    except Exception:
        log.warning("readiness: broker unreachable", exc_info=True)
        checks["broker"] = "down"
    try:
        checks["recovery"] = _recovery(settings, db) if checks["database"] == "up" else "unknown (database down)"
    except Exception:
        log.warning("readiness: recovery lease unreadable", exc_info=True)
        checks["recovery"] = "unknown: the recovery lease could not be read"
    checks.update(storage_checks(settings))  # a full SQLite or data-directory filesystem (app.runtime.disk)
    ok = all(v == "up" for v in checks.values())
    return JSONResponse(status_code=200 if ok else 503, content={"status": "ready" if ok else "not ready", **checks})
