"""``GET /metrics``: Prometheus's text exposition (docs/operations.md lists the metrics).

With ``TRAJLAB_AUTH=required`` a scrape needs an admin key (the counts describe every owner's jobs)
unless ``TRAJLAB_METRICS_PUBLIC=true`` (a scraper on a private network); with auth off it is open like
every route.
"""
from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response

from app.api.access import principal_before_body
from app.api.observability import exposition
from app.kinds import KIND_NAMES
from app.service import breaker as breakers
from app.service.broker import bounded_client
from app.service.metrics import ServiceCollector

router = APIRouter(tags=["health"])


def _collector(request: Request) -> ServiceCollector:
    state = request.app.state
    if getattr(state, "metrics_collector", None) is None:  # one Redis client per process, made on first scrape
        settings = state.settings
        # the request's bound, and the process's breaker: a scrape during a broker loss is not held up by it
        bound = min(settings.broker_probe_timeout_s, breakers.REQUEST_BOUND_S)
        client = bounded_client(settings.broker_url, bound)
        state.metrics_collector = ServiceCollector(state.db, client, KIND_NAMES, breaker=breakers.for_process(settings))
    return state.metrics_collector


@router.get("/metrics", response_class=Response, responses={
    200: {"description": "Prometheus text exposition format 0.0.4", "content": {"text/plain": {}}},
    401: {"description": "No, unknown or revoked API key (TRAJLAB_AUTH=required, TRAJLAB_METRICS_PUBLIC unset)"},
    403: {"description": "The key is not an admin key"}})
async def metrics(request: Request):
    settings = request.app.state.settings
    if settings.auth != "off" and not settings.metrics_public:
        if not (await principal_before_body(request)).admin:
            raise HTTPException(status_code=403, detail="/metrics needs an admin key (or TRAJLAB_METRICS_PUBLIC=true)")
    body, content_type = await run_in_threadpool(exposition, _collector(request))
    return Response(body, media_type=content_type)
