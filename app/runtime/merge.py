"""``deep_merge``: a preset's parameters with a caller's overrides on top.  In the runtime layer, with no
import beyond the standard library, because the command-line client merges ``--set`` onto ``--file`` with it
and must not load the service (FastAPI, pydantic) to send a job (issue 38: the CLI submits in under 0.5 s)."""
from __future__ import annotations

import copy


def deep_merge(base: dict, override: dict) -> dict:
    """``override`` wins; nested dicts merge key by key; lists are replaced whole."""
    out = copy.deepcopy(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out
