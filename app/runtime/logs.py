"""Log lines an operator can follow from one request to its job's worker: ids in context, JSON on demand.

A request's id (``X-Request-ID``, taken from the caller or made here) is held in a context variable for
the request (:func:`log_context`), stored on the job row it creates, and set again by the worker around
the job it runs, with the job's id, kind and owner.  :class:`ContextFilter` copies them onto every
record, so any logger (ours, Celery's, SQLAlchemy's) logged in that context carries them.

``TRAJLAB_LOG_FORMAT=json`` writes one JSON object per line with time, level, logger, message,
request_id, job_id, kind and owner (:class:`JsonFormatter`); nothing else of a record is written, so
no argument that happens to hold a key reaches the log through this formatter.
"""
from __future__ import annotations

import contextvars
import functools
import json
import logging
import logging.config
import re
import uuid
from contextlib import contextmanager
from datetime import datetime, timezone
from typing import Any, Iterator

FIELDS = ("request_id", "job_id", "kind", "owner")
_CONTEXT: dict[str, contextvars.ContextVar[str | None]] = {
    name: contextvars.ContextVar(f"trajlab_{name}", default=None) for name in FIELDS}
# What a caller's X-Request-ID may be: anything else (too long, spaces, control characters) is replaced
# by a fresh id rather than echoed into logs and headers.
_REQUEST_ID = re.compile(r"[A-Za-z0-9._:@/+=-]{1,128}")
TEXT_FORMAT = "%(asctime)s %(name)s %(levelname)s %(message)s"


def request_id_from(header: str | None) -> str:
    """The caller's request id when it is a sane token, else a new one (32 hex digits)."""
    if header and _REQUEST_ID.fullmatch(header):
        return header
    return uuid.uuid4().hex


def current(name: str) -> str | None:
    """The value of one context field (``request_id``, ``job_id``, ``kind``, ``owner``) here, or None."""
    return _CONTEXT[name].get()


@contextmanager
def log_context(**fields: str | None) -> Iterator[None]:
    """Set context fields for the block (and the threads and tasks it starts with a copied context)."""
    tokens = [(_CONTEXT[name], _CONTEXT[name].set(value)) for name, value in fields.items()]
    try:
        yield
    finally:
        for var, token in reversed(tokens):
            var.reset(token)


def bind(**fields: str | None) -> None:
    """Set context fields for the rest of the current context: inside a function run by :func:`isolated`,
    until it returns."""
    for name, value in fields.items():
        _CONTEXT[name].set(value)


def isolated(fn):
    """Run ``fn`` in a copy of the current context, so fields it binds end with the call (a
    worker process runs one job after another in the same thread)."""
    @functools.wraps(fn)
    def run(*args, **kwargs):
        return contextvars.copy_context().run(fn, *args, **kwargs)
    return run


def set_request_id(value: str) -> contextvars.Token:
    """Set the request id for the rest of this context (an ASGI request); reset with the token."""
    return _CONTEXT["request_id"].set(value)


def reset_request_id(token: contextvars.Token) -> None:
    _CONTEXT["request_id"].reset(token)


class ContextFilter(logging.Filter):
    """Copies the context fields onto each record (None when unset), for formatters to use."""

    def filter(self, record: logging.LogRecord) -> bool:
        for name, var in _CONTEXT.items():
            if getattr(record, name, None) is None:
                setattr(record, name, var.get())
        return True


class JsonFormatter(logging.Formatter):
    """One JSON object per line: time (UTC, ISO 8601), level, logger, message and the context fields."""

    def format(self, record: logging.LogRecord) -> str:
        body: dict[str, Any] = {"time": datetime.fromtimestamp(record.created, timezone.utc).isoformat(timespec="milliseconds"),
                "level": record.levelname, "logger": record.name, "message": record.getMessage()}
        for name in FIELDS:
            body[name] = getattr(record, name, None)
        if record.exc_info:
            body["exception"] = self.formatException(record.exc_info)
        return json.dumps(body, default=str)


def dict_config(log_format: str, level: str = "INFO") -> dict:
    """A ``logging.config.dictConfig`` for the root logger and uvicorn's: one stderr handler, the context
    filter, JSON or text lines.  uvicorn applies it in each of its processes (``log_config``)."""
    formatter = {"()": JsonFormatter} if log_format == "json" else {"format": TEXT_FORMAT}
    handler = {"class": "logging.StreamHandler", "formatter": "trajlab", "filters": ["context"],
               "stream": "ext://sys.stderr"}
    inherit = {"handlers": [], "propagate": True}
    return {"version": 1, "disable_existing_loggers": False,
            "filters": {"context": {"()": ContextFilter}},
            "formatters": {"trajlab": formatter},
            "handlers": {"default": handler},
            "root": {"level": level, "handlers": ["default"]},
            "loggers": {"uvicorn": {**inherit, "level": level}, "uvicorn.error": inherit,
                        "uvicorn.access": inherit}}


def configure(log_format: str, level: str | int = "INFO") -> None:
    """Configure this process's logging (the CLI, the recovery loop, the worker)."""
    logging.config.dictConfig(dict_config(log_format, logging.getLevelName(level) if isinstance(level, int)
                                          else level))
