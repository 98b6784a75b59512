"""Request ids and HTTP metrics (one ASGI middleware), and the body of ``GET /metrics``.

Every response carries ``X-Request-ID``: the caller's when it is a sane token, else a new one
(app.runtime.logs); the id is in the logging context for the whole request, so the job a request creates
stores it and the worker logs it again.

HTTP metrics are counted per process.  ``trajlab api`` runs several processes behind one port, and a
scrape lands on any one of them: with ``PROMETHEUS_MULTIPROC_DIR`` set (``trajlab api`` sets it to a
fresh directory before it starts its processes) each process writes its counts to its own file there and
a scrape sums the files, prometheus-client's multiprocess mode.  The job metrics come from the database
and Redis (app.service.metrics), the same whichever process answers.
"""
from __future__ import annotations

import os
import subprocess
import time
from functools import cache
from importlib import metadata
from pathlib import Path

from prometheus_client import CollectorRegistry, Counter, Histogram, disable_created_metrics, generate_latest
from prometheus_client import multiprocess
from prometheus_client.core import GaugeMetricFamily
from prometheus_client.exposition import CONTENT_TYPE_PLAIN_0_0_4

from app.runtime import logs

MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"
# the text format 0.0.4 that every Prometheus parses; no *_created series (a second sample per counter
# that Prometheus of the 0.0.4 format stores as a series of its own)
disable_created_metrics()
# this process's own metrics; in multiprocess mode their values live in files and are read back by
# MultiProcessCollector, so this registry is only exposed when the mode is off
HTTP_REGISTRY = CollectorRegistry(auto_describe=True)
REQUESTS = Counter("trajlab_http_requests", "HTTP requests, by method, route template and status",
                   ["method", "route", "status"], registry=HTTP_REGISTRY)
LATENCY = Histogram("trajlab_http_request_duration_seconds",
                    "Time to the response's last byte, by method, route template and status",
                    ["method", "route", "status"], registry=HTTP_REGISTRY,
                    buckets=(0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10))
# failed API-key attempts (app.api.key_attempts): "invalid" an unknown or revoked key (a 401),
# "refused" an address past the limit (a 429 before any lookup)
AUTH_FAILURES = Counter("trajlab_auth_failures", "Failed API-key attempts: invalid keys and refused addresses",
                        ["outcome"], registry=HTTP_REGISTRY)
UNMATCHED = "unmatched"  # no route: one label value, not one per path a scanner tries


class RequestObservation:
    """Pure ASGI (no BaseHTTPMiddleware: it costs a task and a queue per request)."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        request_id = logs.request_id_from(_header(scope, b"x-request-id"))
        token = logs.set_request_id(request_id)
        started = time.perf_counter()
        status = 500
        header = (b"x-request-id", request_id.encode())

        async def send_with_id(message):
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
                message = {**message, "headers": [*message.get("headers", []), header]}
            await send(message)

        try:
            await self.app(scope, receive, send_with_id)
        finally:
            logs.reset_request_id(token)
            route = scope.get("route")
            labels = (scope["method"], getattr(route, "path", None) or UNMATCHED, str(status))
            REQUESTS.labels(*labels).inc()
            LATENCY.labels(*labels).observe(time.perf_counter() - started)


def _header(scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            return value.decode("latin-1")
    return None


@cache
def build_info() -> tuple[str, str]:
    """(version, commit): the installed package's version; the commit from ``TRAJLAB_COMMIT`` (set by an
    image build), else the source tree's git HEAD, else "unknown"."""
    try:
        version = metadata.version("trajlab")
    except metadata.PackageNotFoundError:
        version = "unknown"
    commit = os.environ.get("TRAJLAB_COMMIT", "")
    if not commit:
        try:
            commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).resolve().parents[2],
                                    capture_output=True, text=True, timeout=5).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            commit = ""
    return version, commit or "unknown"


def exposition(service_collector) -> tuple[bytes, str]:
    """The text exposition of one scrape: HTTP metrics (every API process's), the service's collector,
    build info."""
    registry = CollectorRegistry(auto_describe=False)
    if os.environ.get(MULTIPROC_ENV):
        multiprocess.MultiProcessCollector(registry)
    else:
        registry.register(_Forward(HTTP_REGISTRY))
    registry.register(service_collector)
    registry.register(_BuildInfo())
    return generate_latest(registry), CONTENT_TYPE_PLAIN_0_0_4


class _Forward:
    """A registry's samples, registered in another registry."""

    def __init__(self, source):
        self.source = source

    def collect(self):
        return self.source.collect()


class _BuildInfo:
    def collect(self):
        info = GaugeMetricFamily("trajlab_build_info", "Always 1; the labels name the running build",
                                 labels=["version", "commit"])
        info.add_metric(list(build_info()), 1)
        yield info
