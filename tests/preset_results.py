"""Real results of the kinds' presets, solved once per test session and shared between test modules
(the plots/CSV tests and the result-model drift test read the same solves)."""
from __future__ import annotations

import json
from functools import cache

from app.kinds import KINDS, PRESETS
from app.kinds.base import RunOutcome
from app.service.params import resolve_params
from tests.support import RecordingContext

# Options that make a result carry more of its optional blocks, so more of it is checked.
OVERRIDES = {"long-range-intercept": {"porkchop": {"enabled": True}},
             "robust-max-crossrange": {"monte_carlo": {"samples": 2000}}}


@cache
def _solve(name: str, overrides_json: str) -> tuple[str, dict, RunOutcome]:
    preset = PRESETS[name]
    spec = KINDS[preset.kind]
    params = resolve_params(spec, preset.params, json.loads(overrides_json) or None)
    return preset.kind, params, spec.run(spec.params_model.model_validate(params), RecordingContext())


def solve_preset(name: str, overrides: dict | None = None) -> tuple[str, dict, RunOutcome]:
    """``(kind, resolved params, outcome)`` of a preset with ``overrides`` (default: :data:`OVERRIDES`)."""
    overrides = OVERRIDES.get(name) if overrides is None else overrides
    return _solve(name, json.dumps(overrides or {}, sort_keys=True))
