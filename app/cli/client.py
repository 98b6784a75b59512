"""A small Python client for any trajlab URL (httpx): what the CLI and the tests use, and a notebook can.

    from app.cli.client import Client
    c = Client("http://127.0.0.1:8000")          # or TRAJLAB_URL / TRAJLAB_API_KEY from the environment
    job = c.submit("reentry", preset="betts-max-crossrange", params={"grid": {"intervals": 50}})
    done = c.wait(job["id"])                      # follows the job's Server-Sent Events
    result = c.result(job["id"])
    study = c.submit_study(study_preset="crossrange-vs-heating")   # a trade study: one job per point
    c.wait_study(study["id"]); rows = c.study_result(study["id"])["rows"]

Every non-2xx answer raises :class:`TrajlabError` carrying the status and the
API's one-line message (the 422 ``message`` naming field and rule, or ``detail``).
"""
from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

# httpx's own command line (httpx._main) imports click, rich and pygments whenever they are installed: 80% of
# httpx's import time, paid by every trajlab command for nothing.  httpx imports it under try/except
# ImportError; a None in sys.modules is Python's way to make that import fail (the fallback says to install
# httpx[cli]).  Only when httpx is not loaded yet: a process that loaded it keeps it whole.
if "httpx" not in sys.modules:
    sys.modules.setdefault("httpx._main", None)  # type: ignore[arg-type]
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
        # A plain-http service needs no certificates: loading the system's CA bundle was a tenth of the time
        # a `trajlab submit` took to send its job (redirects are not followed, so no https is reached unverified).
        self.http = http or httpx.Client(base_url=self.url, timeout=timeout,
                                         verify=not self.url.startswith("http://"))

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

    def delete(self, job_id: str) -> None:
        """Delete a job with its result (cancelled first if it is queued or running); 404 afterwards."""
        self._request("DELETE", f"/v1/jobs/{job_id}")

    def usage(self) -> dict:
        """``GET /v1/usage``: the caller's jobs by status, the bytes they keep and the storage quota."""
        return self._request("GET", "/v1/usage").json()

    def result(self, job_id: str) -> dict:
        return self._request("GET", f"/v1/jobs/{job_id}/result").json()

    def result_csv(self, job_id: str, table: str) -> str:
        return self._request("GET", f"/v1/jobs/{job_id}/result.csv", params={"table": table}).text

    def presets(self) -> list[dict]:
        return self._request("GET", "/v1/presets").json()

    def vehicles(self) -> list[dict]:
        return self._request("GET", "/v1/vehicles").json()

    def summary(self, job_id: str) -> dict:
        """What the console's job page leads with: ``headlines`` of a succeeded job, ``failure`` (and
        ``failure_lines``, as the CLI prints it) of a failed one."""
        return self._request("GET", f"/console/jobs/{job_id}/summary").json()

    def numbers(self, job_id: str) -> dict:
        """The key numbers of a succeeded job (empty otherwise), as the console's job page shows them."""
        return self._request("GET", f"/console/jobs/{job_id}/numbers").json()

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

    # --- the operator's (an admin key; /v1/admin) -------------------------------------------
    def create_key(self, *, name: str, owner: str | None = None, admin: bool = False) -> dict:
        """A new API key: its info and ``key``, the only time it is shown."""
        return self._request("POST", "/v1/admin/keys", json={"name": name, "owner": owner, "admin": admin}).json()

    def list_keys(self) -> list[dict]:
        return self._request("GET", "/v1/admin/keys").json()

    def revoke_key(self, name: str) -> None:
        self._request("DELETE", f"/v1/admin/keys/{name}")

    def purge(self, *, older_than_days: float, statuses: list[str] | None = None, dry_run: bool = False) -> dict:
        body: dict = {"older_than_days": older_than_days, "dry_run": dry_run}
        if statuses:
            body["statuses"] = statuses
        return self._request("POST", "/v1/admin/purge", json=body).json()

    def backup(self, dest, *, timeout: float = 3600.0) -> int:
        """Download a backup of the service's database to ``dest`` (written beside it, then renamed: an
        interrupted download never leaves a file that looks whole); the bytes written."""
        from pathlib import Path

        dest = Path(dest)
        partial = dest.with_name(dest.name + ".partial")
        try:
            with self.http.stream("GET", "/v1/admin/backup", headers=self.headers,
                                  timeout=httpx.Timeout(30.0, read=timeout)) as r:
                if r.status_code >= 400:
                    r.read()
                    msg, body = _message(r)
                    raise TrajlabError(r.status_code, msg, body)
                with open(partial, "wb") as f:
                    f.writelines(r.iter_bytes())
        except httpx.TransportError as exc:
            partial.unlink(missing_ok=True)
            raise TrajlabError(0, f"cannot reach trajlab at {self.url} ({type(exc).__name__}); "
                                  f"is it running? (trajlab serve, or set TRAJLAB_URL)") from None
        except BaseException:
            partial.unlink(missing_ok=True)
            raise
        partial.replace(dest)
        return dest.stat().st_size

    # --- studies ---------------------------------------------------------------------------
    def submit_study(self, *, study_preset: str | None = None, kind: str | None = None, preset: str | None = None,
                     params: dict | None = None, sweeps: list[dict] | None = None, mode: str | None = None,
                     label: str | None = None) -> dict:
        """``POST /v1/studies``: a named study, or a base job (kind, preset, params) with ``sweeps`` and ``mode``;
        what is given overrides the named study's own."""
        body = {k: v for k, v in {"study_preset": study_preset, "kind": kind, "preset": preset, "params": params,
                                  "sweeps": sweeps, "mode": mode, "label": label}.items() if v is not None}
        return self._request("POST", "/v1/studies", json=body).json()

    def study(self, study_id: str) -> dict:
        return self._request("GET", f"/v1/studies/{study_id}").json()

    def list_studies(self, *, limit: int = 50, offset: int = 0) -> list[dict]:
        return self._request("GET", "/v1/studies", params={"limit": limit, "offset": offset}).json()

    def study_result(self, study_id: str) -> dict:
        """``{"study": ..., "rows": [...]}``: one row per point (swept values, status, key numbers, job id)."""
        return self._request("GET", f"/v1/studies/{study_id}/result").json()

    def study_result_csv(self, study_id: str) -> str:
        return self._request("GET", f"/v1/studies/{study_id}/result", params={"format": "csv"}).text

    def cancel_study(self, study_id: str) -> dict:
        return self._request("POST", f"/v1/studies/{study_id}/cancel").json()

    def delete_study(self, study_id: str) -> None:
        """Delete a study with every point job (running points cancelled first)."""
        self._request("DELETE", f"/v1/studies/{study_id}")

    def wait_study(self, study_id: str, *, on_update: Callable[[dict], None] | None = None,
                   timeout: float | None = None, poll_s: float = 1.0) -> dict:
        """Poll the study until it is no longer running (a study has no event stream: its points do);
        ``on_update`` gets each new document."""
        deadline = None if timeout is None else time.monotonic() + timeout
        seen = False
        while True:
            try:
                study = self.study(study_id)
                seen = True
            except TrajlabError as exc:
                if exc.status_code != 0 or not seen:
                    raise
                time.sleep(poll_s)  # a moment without the service it reached before (a restart): try again
                continue
            if on_update is not None:
                on_update(study)
            if study["status"] != "running":
                return study
            if deadline is not None and time.monotonic() >= deadline:
                raise TimeoutError(f"study {study_id} did not finish within {timeout} s")
            time.sleep(poll_s)
