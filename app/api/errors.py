"""Error bodies: 422s that name the field and the rule and survive any input, and a generic 500.

A 422 never echoes more than a few hundred characters of the input (a 10 MB
label came back as a 10 MB body), and no error body carries an exception's
text, an address, a path or a trace: a 500 says only "internal error" and a
request id, and the traceback goes to the log under that id.  A database that cannot be reached, or
whose disk is full, is a 503 with Retry-After.
"""
from __future__ import annotations

import logging
import math
import uuid

from fastapi import Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from app.runtime.disk import is_disk_full

log = logging.getLogger("trajlab.errors")

MAX_ECHO_CHARS = 200  # of one string echoed back in a 422
MAX_ECHO_ITEMS = 20  # of one list or dict echoed back
MAX_ERRORS = 20  # errors listed in one 422


def _short(text: str) -> str:
    # backslashreplace: a lone surrogate would make the JSON response itself unencodable
    text = text if len(text) <= MAX_ECHO_CHARS else f"{text[:MAX_ECHO_CHARS]}... ({len(text)} characters)"
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


def _json_safe(value, depth: int = 0):
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)  # "nan", "inf": the JSON response cannot carry the number itself
    if depth > 4:
        return "..."
    if isinstance(value, str):
        return _short(value)
    if isinstance(value, dict):
        return {_short(str(k)): _json_safe(v, depth + 1) for k, v in list(value.items())[:MAX_ECHO_ITEMS]}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v, depth + 1) for v in list(value)[:MAX_ECHO_ITEMS]]
    if value is None or isinstance(value, (int, float, bool)):
        return value
    return _short(repr(value))


def _field(loc) -> str:
    parts = [str(p) for p in loc if p != "body"]
    return ".".join(parts) or "body"


async def validation_error_handler(request: Request, exc: Exception) -> JSONResponse:
    # typed as Starlette's handlers are (any exception); registered for RequestValidationError only
    assert isinstance(exc, RequestValidationError)
    errors = list(exc.errors())
    detail = []
    for err in errors[:MAX_ERRORS]:
        loc = [_json_safe(p) for p in err.get("loc", ())]
        msg = str(err.get("msg", ""))
        # a literal_error's message lists the allowed values (ours, not the caller's text): cut, it hid the
        # valid preset names a mistyped one needs
        item = {"loc": loc, "msg": msg if err.get("type") == "literal_error" else _short(msg), "type": err.get("type", "")}
        if "input" in err:
            item["input"] = _json_safe(err["input"])
        detail.append(item)
    message = "; ".join(f"{_field(d['loc'])}: {d['msg']}" for d in detail)
    if len(errors) > MAX_ERRORS:
        message += f"; and {len(errors) - MAX_ERRORS} more errors"
    return JSONResponse(status_code=422, content={"detail": detail, "message": message})


# The service's refusals (registered in create_app, which imports the service; typed as Starlette's handlers are)
async def invalid_params_handler(request: Request, exc: Exception) -> JSONResponse:
    """The service's parameter errors: the 422 of a request body that failed validation, at body.params."""
    from app.service.params import InvalidParams

    assert isinstance(exc, InvalidParams)
    errors = [{**err, "loc": ("body", *err["loc"])} for err in exc.errors]
    return await validation_error_handler(request, RequestValidationError(errors))


async def refused_handler(request: Request, exc: Exception) -> JSONResponse:
    """A submission the service did not admit (app.service.submit): a 422 with its reason."""
    from app.service.submit import Refused

    assert isinstance(exc, Refused)
    return JSONResponse(status_code=422, content={"detail": exc.message})


async def quota_exceeded_handler(request: Request, exc: Exception) -> JSONResponse:
    """Over the owner's quota: a 429 saying when to try again."""
    from app.service.quota import QuotaExceeded

    assert isinstance(exc, QuotaExceeded)
    return JSONResponse(status_code=429, headers={"Retry-After": str(exc.retry_after_s)},
                        content={"detail": exc.message})


async def internal_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """Any unhandled exception: logged with its traceback under a request id; the client gets only the id."""
    request_id = uuid.uuid4().hex
    log.error("unhandled error on %s %s (request %s)", request.method, request.url.path, request_id,
              exc_info=exc)
    return JSONResponse(status_code=500, headers={"X-Request-ID": request_id},
                        content={"detail": "internal error; the service log has the details under this request id",
                                 "request_id": request_id})


DATABASE_RETRY_AFTER_S = 5


# A full disk needs someone to free space: clients come back later than after an outage's restart.
DISK_FULL_RETRY_AFTER_S = 15


async def database_unavailable_handler(request: Request, exc: Exception) -> JSONResponse:
    """The database did not answer (outage, restart, pool exhausted) or its disk is full: 503 with
    Retry-After, never a 500.  Nothing was stored by the request (the transaction rolled back); the
    address and the driver's text stay in the log."""
    if is_disk_full(exc):
        log.warning("database disk full on %s %s: %s", request.method, request.url.path, type(exc).__name__)
        return JSONResponse(status_code=503, headers={"Retry-After": str(DISK_FULL_RETRY_AFTER_S)},
                            content={"detail": "the database's disk is full; nothing was stored, retry later",
                                     "message": "the database's disk is full; retry later"})
    log.warning("database unavailable on %s %s: %s", request.method, request.url.path, type(exc).__name__)
    return JSONResponse(status_code=503, headers={"Retry-After": str(DATABASE_RETRY_AFTER_S)},
                        content={"detail": "the database is unavailable; nothing was stored, retry later",
                                 "message": "the database is unavailable; retry later"})
