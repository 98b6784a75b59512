"""Registry of job kinds: each ``app/kinds/<kind>.py`` exposes ``SPEC: KindSpec``."""
from __future__ import annotations

import importlib
import importlib.util

from app.kinds.base import KindSpec, Preset

KIND_NAMES = ("reentry", "robust_reentry", "midcourse", "intercept", "ocp")


def _load() -> dict[str, KindSpec]:
    specs = {}
    for name in KIND_NAMES:
        if importlib.util.find_spec(f"app.kinds.{name}") is None:
            continue  # a test asserts that every kind of the API contract is registered
        module = importlib.import_module(f"app.kinds.{name}")
        specs[name] = module.SPEC
    return specs


KINDS: dict[str, KindSpec] = _load()
PRESETS: dict[str, Preset] = {p.name: p for spec in KINDS.values() for p in spec.presets}
