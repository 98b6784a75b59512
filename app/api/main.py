"""FastAPI application factory."""
from __future__ import annotations

from contextlib import asynccontextmanager
from typing import Any

import anyio.to_thread
from fastapi import Depends, FastAPI
from fastapi.middleware.gzip import GZipMiddleware
from fastapi.exceptions import RequestValidationError
from sqlalchemy.exc import DBAPIError, OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeout

from app.runtime.db import POOL_SIZE, get_database
from app.api.errors import (database_unavailable_handler, internal_error_handler, invalid_params_handler,
                            quota_exceeded_handler, refused_handler, validation_error_handler)
from app.api.limits import reject_unsafe_text
from app.api.security_headers import SecurityHeaders
from app.api.observability import RequestObservation
from app.runtime.settings import Settings, get_settings
from app.service.publisher import Publisher

DESCRIPTION = """
Trajectory optimization as a job service. Submit a job (`POST /v1/jobs`) with a
`kind` and a named `preset` and/or `params`; poll `GET /v1/jobs/{id}` for
`status`, `progress` and `message`; fetch `GET /v1/jobs/{id}/result`.

Units: SI everywhere (m, m/s, s, kg, N, W/m^2, J/m^2), angles in degrees; field
names carry the unit (`altitude_m`, `flight_path_deg`, `tf_s`).
"""


@asynccontextmanager
async def _lifespan(_app: FastAPI):
    # Sync routes run in anyio's thread pool, 40 threads by default: with 40 requests holding the GIL in turn
    # and waiting for 16 pooled connections, POST at 100 connections had a p99 of 1.5 s; one thread per
    # pooled connection (requests then wait their turn in order, on the event loop) cut it to 0.7-1.0 s
    # at the same throughput (benchmarks/api_load.py, 2 shared cores); app.runtime.db.POOL_SIZE says why 8 per process.
    anyio.to_thread.current_default_thread_limiter().total_tokens = POOL_SIZE
    yield


def create_app(settings: Settings | None = None) -> FastAPI:
    from app.api.routes import (admin, console, console_summary, docs, events, guide, health, jobs, lambert,  # after settings:
                                metrics, presets, results, studies, usage, vehicles)  # routes read the registry
    from app.service.broker import create_publisher
    from app.api.schemas import ValidationErrorBody
    from app.service.params import InvalidParams
    from app.service.quota import QuotaExceeded
    from app.service.submit import Refused

    settings = settings or get_settings()
    # max_body_size: FastAPI's own cap (413 on Content-Length or streamed bytes, before parsing);
    # reject_unsafe_text: NUL and lone surrogates are a 422 (app.api.limits).
    app = FastAPI(title="trajlab", version="0.1.0", description=DESCRIPTION, docs_url=None, redoc_url=None,
                  lifespan=_lifespan,
                  # operation ids are the route functions' names (submit_job, get_result, ...): what client
                  # generators turn into method names
                  generate_unique_id_function=lambda route: route.name,
                  max_body_size=settings.max_body_bytes, dependencies=[Depends(reject_unsafe_text)],
                  # every route can 422 (reject_unsafe_text); the body is the handler's, not FastAPI's default
                  responses={422: {"model": ValidationErrorBody, "description": "Invalid request: the message "
                                                                               "names the field and the rule"}})
    app.add_exception_handler(RequestValidationError, validation_error_handler)
    # the service's refusals (app.service.submit), as the routes answered them before the service raised them
    app.add_exception_handler(InvalidParams, invalid_params_handler)
    app.add_exception_handler(Refused, refused_handler)
    app.add_exception_handler(QuotaExceeded, quota_exceeded_handler)
    app.add_exception_handler(Exception, internal_error_handler)
    for exc_type in (OperationalError, DBAPIError, PoolTimeout):  # a database outage is a 503, not a 500
        app.add_exception_handler(exc_type, database_unavailable_handler)
    # gzip above 1 kB: result JSON compresses ~5x; Starlette leaves text/event-stream alone
    app.add_middleware(GZipMiddleware, minimum_size=1000)
    # CSP, frame refusal, nosniff and Referrer-Policy on the console's and the docs' pages (issue 30)
    app.add_middleware(SecurityHeaders)
    # outermost: the request id and the HTTP metrics see every response, errors and gzip included
    app.add_middleware(RequestObservation)
    if settings.trusted_proxies.strip():
        # outside even that: the client address everything reads (the failed-key limit, the logs) is a trusted
        # proxy's X-Forwarded-For (the rightmost address it did not add itself), never a header any client
        # sets; `trajlab api`/`serve` switch uvicorn's own reading off, which trusts 127.0.0.1 by default
        from uvicorn.middleware.proxy_headers import ProxyHeadersMiddleware

        app.add_middleware(ProxyHeadersMiddleware, trusted_hosts=settings.trusted_proxies)
    app.state.settings = settings
    app.state.db = get_database(settings.database_url, settings)
    app.state.celery = create_publisher(settings)
    # job messages leave from the publisher's thread, never from a request (app.service.publisher)
    app.state.publisher = Publisher(app.state.db, app.state.celery, settings)
    bad_body: dict[int | str, dict[str, Any]] = {400: {"description": "The body is not valid JSON (e.g. not UTF-8)"},
                413: {"description": "The body is larger than TRAJLAB_MAX_BODY_BYTES (refused before parsing)"}}
    needs_key: dict[int | str, dict[str, Any]] = {401: {"description": "No, unknown or revoked API key (TRAJLAB_AUTH=required)"},
                 429: {"description": "Too many failed API-key attempts from this address (TRAJLAB_AUTH_MAX_FAILURES); "
                                       "`Retry-After` says when to try again"}}
    app.include_router(jobs.router, responses=bad_body | needs_key)
    app.include_router(events.router, responses=needs_key)
    app.include_router(results.router, responses=needs_key)
    app.include_router(console.router)
    app.include_router(console_summary.router)
    console.mount_static(app)
    app.include_router(presets.router)
    app.include_router(vehicles.router)
    app.include_router(studies.router, responses=bad_body | needs_key)
    app.include_router(usage.router, responses=needs_key)
    app.include_router(admin.router, responses=bad_body | needs_key)
    app.include_router(lambert.router, responses=bad_body | needs_key, max_body_size=lambert.max_body_bytes(settings))
    app.include_router(health.router)
    app.include_router(metrics.router)
    docs.mount(app)  # /docs and /redoc from packaged assets: they work offline
    guide.mount(app)  # /guide: the user guide (MkDocs) built by `make guide`
    return app
