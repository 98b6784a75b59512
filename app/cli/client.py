"""A small Python client for any trajlab URL (httpx): what the CLI and the tests use, and a notebook can.

    from app.cli.client import Client
    c = Client("http://127.0.0.1:8000")          # or TRAJLAB_URL / TRAJLAB_API_KEY from the environment
    job = c.submit("reentry", preset="betts-max-crossrange", params={"grid": {"intervals": 50}})
    done = c.wait(job["id"])                      # follows the job's Server-Sent Events
    result = c.result(job["id"])

Every non-2xx answer raises :class:`TrajlabError` carrying the status and the
API's one-line message (the 422 ``message`` naming field and rule, or ``detail``).
"""
from __future__ import annotations

import json
import os
import time
from typing import Any, Callable, Iterator

import httpx

FINAL_STATUSES = ("succeeded", "failed", "cancelled")
DEFAULT_URL = "http://127.0.0.1:8000"


EVENTS_READ_TIMEOUT_S = 45.0  # three of the event stream's 15 s pings


class TrajlabError(Exception):
    """An HTTP error answer of the service, with its one-line message."""

    def __init__(self, status_code: int, message: str, body: Any = None):
        super().__init__(f"{status_code}: {message}")
        self.status_code = status_code
        self.message = message
        self.body = body


def _message(response: httpx.Response) -> tuple[str, Any]:
    try:
        body = response.json()
    except ValueError:
        return (response.text.strip()[:500] or response.reason_phrase), None
    if isinstance(body, dict):
        msg = body.get("message") or body.get("detail")
        if isinstance(msg, list):  # pydantic's list without our one-line message
            msg = "; ".join(str(d.get("msg", d)) for d in msg)
        return str(msg or body), body
    return str(body), body


def parse_sse(lines: Iterator[str]) -> Iterator[dict]:
    """Events ``{"event", "id", "data"}`` of a ``text/event-stream`` (data JSON-decoded; comments skipped)."""
    event: dict = {}
    for line in lines:
        if line == "":
            if "data" in event:
                event["data"] = json.loads(event["data"])
                yield event
            event = {}
        elif not line.startswith(":"):
            field, _, value = line.partition(":")
            value = value.removeprefix(" ")
            if field == "data" and "data" in event:
                event["data"] += "\n" + value
            elif field in ("event", "id", "data", "retry"):
                event[field] = value


class Client:
    """HTTP client of one trajlab service. ``http`` may be any ``httpx.Client`` (e.g. FastAPI's TestClient)."""

    def __init__(self, url: str | None = None, *, api_key: str | None = None, timeout: float = 30.0,
                 http: httpx.Client | None = None):
        local = f"http://127.0.0.1:{os.environ['TRAJLAB_PORT']}" if os.environ.get("TRAJLAB_PORT") else DEFAULT_URL
        self.url = (url or os.environ.get("TRAJLAB_URL") or local).rstrip("/")
        key = api_key if api_key is not None else os.environ.get("TRAJLAB_API_KEY")
        self.headers = {"Authorization": f"Bearer {key}"} if key else {}
        self.http = http or httpx.Client(base_url=self.url, timeout=timeout)

    # --- plumbing ------------------------------------------------------------------------
    def _request(self, method: str, path: str, **kw) -> httpx.Response:
        headers = {**self.headers, **kw.pop("headers", {})}
        try:
            r = self.http.request(method, path, headers=headers, **kw)
        except httpx.TransportError as exc:
            raise TrajlabError(0, f"cannot reach trajlab at {self.url} ({type(exc).__name__}); "
                                  f"is it running? (trajlab serve, or set TRAJLAB_URL)") from None
        if r.status_code >= 400:
            msg, body = _message(r)
            raise TrajlabError(r.status_code, msg, body)
        return r

    # --- jobs ----------------------------------------------------------------------------
    def submit(self, kind: str, *, preset: str | None = None, params: dict | None = None,
               label: str | None = None) -> dict:
        body: dict = {"kind": kind}
        if preset:
            body["preset"] = preset
        if params:
            body["params"] = params
        if label:
            body["label"] = label
        return self._request("POST", "/v1/jobs", json=body).json()

    def job(self, job_id: str) -> dict:
        return self._request("GET", f"/v1/jobs/{job_id}").json()

    def jobs(self, *, kind: str | None = None, status: str | None = None, limit: int = 50,
             offset: int = 0) -> dict:
        query = {k: v for k, v in {"kind": kind, "status": status, "limit": limit, "offset": offset}.items()
                 if v is not None}
        return self._request("GET", "/v1/jobs", params=query).json()

    def cancel(self, job_id: str) -> dict:
        return self._request("POST", f"/v1/jobs/{job_id}/cancel").json()

    def result(self, job_id: str) -> dict:
        return self._request("GET", f"/v1/jobs/{job_id}/result").json()

    def result_csv(self, job_id: str, table: str) -> str:
        return self._request("GET", f"/v1/jobs/{job_id}/result.csv", params={"table": table}).text

    def presets(self) -> list[dict]:
        return self._request("GET", "/v1/presets").json()

    def events(self, job_id: str, *, last_event_id: str | None = None) -> Iterator[dict]:
        """The job's events until its final one (``event == "end"``)."""
        headers = {**self.headers, **({"Last-Event-ID": last_event_id} if last_event_id else {})}
        # the stream sends a ping every 15 s (app.api.routes.events): 45 s of silence is a dead link
        with self.http.stream("GET", f"/v1/jobs/{job_id}/events", headers=headers,
                              timeout=httpx.Timeout(30.0, read=EVENTS_READ_TIMEOUT_S)) as r:
            if r.status_code >= 400:
                r.read()
                msg, body = _message(r)
                raise TrajlabError(r.status_code, msg, body)
            yield from parse_sse(r.iter_lines())

    def wait(self, job_id: str, *, on_event: Callable[[dict], None] | None = None,
             timeout: float | None = None) -> dict:
        """Follow the job to a final status (reconnecting where a stream broke); its final document."""
        deadline = None if timeout is None else time.monotonic() + timeout
        last: str | None = None
        while deadline is None or time.monotonic() < deadline:
            try:
                for ev in self.events(job_id, last_event_id=last):
                    last = ev.get("id", last)
                    if on_event is not None:
                        on_event(ev)
                    if ev["event"] == "end":
                        return self.job(job_id)
            except httpx.TransportError:
                time.sleep(1.0)  # a dropped stream: resume after the last event seen
                continue
            job = self.job(job_id)  # the stream ended without "end" (server restart): look, then resume
            if job["status"] in FINAL_STATUSES:
                return job
        raise TimeoutError(f"job {job_id} did not finish within {timeout} s")
