"""Typed result models: the base every kind's result model derives from (``ResultModel``, ``Num``, ``Series``).

What this module is for: ``GET /v1/jobs/{id}/result`` and ``/docs`` show each kind's result with
its fields and units (issue 13 item 6).  A kind declares its model in ``SPEC.result_model``; the
models live in ``app/kinds/<kind>/result_model.py`` (robust_reentry reuses the reentry blocks of
:mod:`app.kinds.reentry.result_model`).  The models describe the JSON the kinds write (``app.kinds.base.json_value``), they
do not produce it: ``tests/unit/test_result_models.py`` validates every preset's real result with
undeclared fields forbidden, so a field added to a result without its model fails a test.

Conventions:
- every number is ``float | None``: one policy for non-finite values, ``null`` (never ``0.0`` or
  ``"nan"``); ``allow_inf_nan=False`` makes a NaN that slipped through a validation error;
- units are in the field names (``_m``, ``_mps``, ``_deg``, ``_w_m2``) and spelled out in the
  descriptions;
- a field the result only sometimes has (an option, a path limit, the compact vs full body of
  ``?include=``) has a default of ``None``;
- ``extra="allow"``: the published schema lets a client keep fields added later
  (``additionalProperties``); the drift test is what keeps the models complete.
"""
from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field


class ResultModel(BaseModel):
    """Base of the result models: extra fields are kept (forward compatible), NaN/inf are rejected."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)


Num = float | None          # a number; null when not finite
Series = list[float | None]  # a time series or curve; null where not finite


def series(what: str, unit: str) -> Any:
    """A required series field described with its unit (a FieldInfo, typed Any as pydantic's Field is:
    it stands as the default of a field of another type)."""
    return Field(description=f"{what} ({unit}), one value per time point; null where not finite")
