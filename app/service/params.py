"""Resolving a submission's parameters: preset, then the user's overrides, then validation."""
from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import ValidationError

from app.runtime.merge import deep_merge  # re-exported: its callers import it from here

if TYPE_CHECKING:  # importing app.kinds.base loads the registry of kinds: deep_merge alone needs none
    from app.kinds.base import KindSpec

__all__ = ["InvalidParams", "deep_merge", "resolve_params"]


class InvalidParams(Exception):
    """Parameters that break a rule: ``errors`` in pydantic's form (``loc``, ``msg``, ``type``, ``input``),
    each ``loc`` starting at ``"params"``; the API answers a 422 naming ``body.params.<field>``."""

    def __init__(self, errors: list[dict]):
        super().__init__("; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in errors))
        self.errors = errors


def resolve_params(spec: KindSpec, preset_params: dict | None, overrides: dict | None) -> dict:
    """The fully resolved parameter set (defaults filled in), as stored on the job.

    Raises :class:`InvalidParams` when the merged set breaks a rule that only shows once preset and
    overrides meet.
    """
    merged = deep_merge(preset_params or {}, overrides or {})
    try:
        model = spec.params_model.model_validate(merged)
    except ValidationError as exc:
        errors: list[dict] = []
        for err in exc.errors(include_url=False):
            item = {k: v for k, v in err.items() if k != "ctx"}
            item["loc"] = ("params", *err.get("loc", ()))
            errors.append(item)
        raise InvalidParams(errors) from None
    return model.model_dump(mode="json")
