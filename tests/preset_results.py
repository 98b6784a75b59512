"""Real results of the kinds' presets, solved once per test session and shared between test modules
(the plots/CSV tests, the result-model drift test, the ocp catalogue and golden tests, the progress of a
robust job: each reads the same solves).  A module that reads them is in the "presets" group of
tests/conftest.py, so under xdist it runs in the worker that holds the cache."""
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
def _solve(name: str, overrides_json: str) -> tuple[str, dict, RunOutcome, tuple]:
    preset = PRESETS[name]
    spec = KINDS[preset.kind]
    params = resolve_params(spec, preset.params, json.loads(overrides_json) or None)
    ctx = RecordingContext()
    outcome = spec.run(spec.params_model.model_validate(params), ctx)
    return preset.kind, params, outcome, tuple(ctx.messages)


def _key(name: str, overrides: dict | None) -> tuple[str, str]:
    overrides = OVERRIDES.get(name) if overrides is None else overrides
    return name, json.dumps(overrides or {}, sort_keys=True)


def solve_preset(name: str, overrides: dict | None = None) -> tuple[str, dict, RunOutcome]:
    """``(kind, resolved params, outcome)`` of a preset with ``overrides`` (default: :data:`OVERRIDES`)."""
    return _solve(*_key(name, overrides))[:3]


def preset_progress(name: str, overrides: dict | None = None) -> list[tuple[float, object]]:
    """The progress messages (``(fraction, message)``, in order) that :func:`solve_preset`'s run sent."""
    return list(_solve(*_key(name, overrides))[3])
