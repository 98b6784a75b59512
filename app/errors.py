"""422 responses that name the field and the rule, and survive any input (NaN included)."""
from __future__ import annotations

import math

from fastapi import Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse


def _json_safe(value, depth: int = 0):
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)  # "nan", "inf": the JSON response cannot carry the number itself
    if depth > 4:
        return "..."
    if isinstance(value, dict):
        return {str(k): _json_safe(v, depth + 1) for k, v in list(value.items())[:50]}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v, depth + 1) for v in list(value)[:50]]
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return repr(value)


def _field(loc) -> str:
    parts = [str(p) for p in loc if p != "body"]
    return ".".join(parts) or "body"


async def validation_error_handler(request: Request, exc: RequestValidationError) -> JSONResponse:
    detail = []
    for err in exc.errors():
        item = {"loc": list(err.get("loc", ())), "msg": err.get("msg", ""), "type": err.get("type", "")}
        if "input" in err:
            item["input"] = _json_safe(err["input"])
        detail.append(item)
    message = "; ".join(f"{_field(d['loc'])}: {d['msg']}" for d in detail)
    return JSONResponse(status_code=422, content={"detail": detail, "message": message})
