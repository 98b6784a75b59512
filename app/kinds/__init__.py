"""Registry of job kinds: each package ``app/kinds/<kind>/`` exposes ``SPEC: KindSpec``; its plots are handed to
:mod:`app.results.plots` here (the machinery sits below the kinds and never imports them)."""
from __future__ import annotations

import importlib
import importlib.util

from app.kinds.base import KindSpec, Preset
from app.results.plots import register_plots

KIND_NAMES = ("reentry", "robust_reentry", "midcourse", "intercept", "ocp")


def _load() -> dict[str, KindSpec]:
    specs = {}
    for name in KIND_NAMES:
        if importlib.util.find_spec(f"app.kinds.{name}") is None:
            continue  # a test asserts that every kind of the API contract is registered
        module = importlib.import_module(f"app.kinds.{name}")
        specs[name] = module.SPEC
        if module.SPEC.plots is not None:
            register_plots(name, module.SPEC.plots)
    return specs


KINDS: dict[str, KindSpec] = _load()
PRESETS: dict[str, Preset] = {p.name: p for spec in KINDS.values() for p in spec.presets}
