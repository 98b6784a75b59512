"""Input limits checked on the raw request body, before pydantic sees it.

* The body size itself is capped by FastAPI's own ``max_body_size`` (Starlette's
  ``RequestBodyLimitMiddleware``: a ``Content-Length`` over the cap, or streamed
  bytes past it, give 413 before anything is parsed); see ``create_app``.
* :func:`reject_unsafe_text`: JSON may spell a NUL (``\\u0000``) or a lone UTF-16
  surrogate (``\\ud800``) as an escape.  Python accepts both, but PostgreSQL
  refuses NUL in text, and a lone surrogate cannot be encoded to UTF-8 by any
  database driver or by the JSON response, so they were 500s.  No field of ours
  needs either, so any request body that contains one is a 422.  The scan is a
  regular expression over the bytes (C speed, about 1 ms per MB).
* :func:`count_lambert_problems`: an upper bound on the problems in a Lambert
  body without parsing it (see there).
"""
from __future__ import annotations

import re

from fastapi import Request
from fastapi.exceptions import RequestValidationError

# Candidate escapes; whether the backslash is itself escaped is checked per hit
# (a pattern starting with a literal is searched at memchr speed; a look-behind is not).
_CANDIDATE = re.compile(rb"\\u(0000|[dD][89a-fA-F][0-9a-fA-F]{2})")

BODY_METHODS = frozenset({"POST", "PUT", "PATCH"})
_LONE = "strings must not contain lone UTF-16 surrogates (e.g. \\ud800)"


def _is_escape(body: bytes, at: int) -> bool:
    """True if the backslash at ``at`` starts an escape (an even number of backslashes before it)."""
    k = at
    while k > 0 and body[k - 1] == 0x5C:
        k -= 1
    return (at - k) % 2 == 0


def unsafe_text(body: bytes) -> str | None:
    """Why ``body`` (raw JSON) holds a string no database or response can carry, or None."""
    pending_high: int | None = None  # end offset of a high surrogate escape awaiting its low half
    for m in _CANDIDATE.finditer(body):
        if not _is_escape(body, m.start()):
            continue
        code = m.group(1)
        if code == b"0000":
            return "strings must not contain NUL characters (\\u0000)"
        if code[1:2] in b"89abAB":  # high half
            if pending_high is not None:
                return _LONE
            pending_high = m.end()
        elif pending_high == m.start():
            pending_high = None  # a valid pair: one character outside the BMP
        else:
            return _LONE
    if pending_high is not None:
        return _LONE
    return None


async def reject_unsafe_text(request: Request) -> None:
    """App-wide dependency: a 422 for a body holding NUL or a lone surrogate (FastAPI has read
    the body already; dependencies run before the body is validated)."""
    if request.method not in BODY_METHODS:
        return
    reason = unsafe_text(await request.body())
    if reason is not None:
        raise RequestValidationError([{"loc": ("body",), "type": "string_unsafe", "msg": reason}])


def count_lambert_problems(body: bytes) -> int:
    """An upper bound on the problems of a raw ``POST /v1/lambert`` body: the occurrences of the
    required key ``"tof_s"``.  Every valid problem has it once and no other field may
    (unknown keys are rejected, values are numbers), so a body with more is over the cap or
    invalid either way.  A client can hide keys from this count with \\u escapes; the exact
    count after parsing still applies and the body size cap bounds what that costs."""
    return body.count(b'"tof_s"')
