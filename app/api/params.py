"""Resolving a submission's parameters: preset, then the user's overrides, then validation."""
from __future__ import annotations

from typing import Any

from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from app.kinds.base import KindSpec
from app.runtime.merge import deep_merge  # re-exported: its callers import it from here


def resolve_params(spec: KindSpec, preset_params: dict | None, overrides: dict | None) -> dict:
    """The fully resolved parameter set (defaults filled in), as stored on the job.

    Raises ``RequestValidationError`` (a 422 naming ``body.params.<field>``) when
    the merged set breaks a rule that only shows once preset and overrides meet.
    """
    merged = deep_merge(preset_params or {}, overrides or {})
    try:
        model = spec.params_model.model_validate(merged)
    except ValidationError as exc:
        errors = []
        for details in exc.errors(include_url=False):
            err: dict[str, Any] = dict(details)
            err["loc"] = ("body", "params", *err.get("loc", ()))
            err.pop("ctx", None)
            errors.append(err)
        raise RequestValidationError(errors) from None
    return model.model_dump(mode="json")
