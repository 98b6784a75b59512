"""Registry of job kinds: each package ``app/kinds/<kind>/`` exposes ``SPEC: KindSpec``; its plots, CSV tables
and default result body are handed to :mod:`app.results` here (the machinery sits below the kinds and never
imports them).

A kind outside this package (a plugin: your own ``mypackage.orbit_raise`` module with a ``SPEC``) is
registered with :func:`register_kind`, or named in ``TRAJLAB_EXTRA_KINDS`` (comma-separated module
paths), which this registry reads when it is first imported, so that the API process and every worker
know the same kinds before the submission schema is built from them (``app.api.schemas``).
"""
from __future__ import annotations

import importlib
import importlib.util
import os

from app.kinds.base import KindSpec, Preset
from app.results.compact import register_compaction
from app.results.plots import register_plots
from app.results.tables import register_tables

KIND_NAMES = ("reentry", "robust_reentry", "midcourse", "intercept", "ocp")
EXTRA_KINDS_ENV = "TRAJLAB_EXTRA_KINDS"

KINDS: dict[str, KindSpec] = {}
PRESETS: dict[str, Preset] = {}


def register_kind(spec: KindSpec) -> KindSpec:
    """Make ``spec`` a kind of this process: its presets, plots, tables and default body.

    Call it before ``app.api`` is imported (the submission schema is built from the registry then) and in
    every process that runs jobs; ``TRAJLAB_EXTRA_KINDS`` does both for a kind in a module of its own.
    A kind name or preset name already taken is a ``ValueError``: a kind is declared once.
    """
    if spec.kind in KINDS and KINDS[spec.kind] is not spec:
        raise ValueError(f"kind {spec.kind} is already registered")
    taken = [p.name for p in spec.presets if p.name in PRESETS and PRESETS[p.name].kind != spec.kind]
    if taken:
        raise ValueError(f"preset names {taken} of kind {spec.kind} are taken by other kinds")
    KINDS[spec.kind] = spec
    PRESETS.update({p.name: p for p in spec.presets})
    if spec.plots is not None:
        register_plots(spec.kind, spec.plots)
    register_tables(spec.kind, spec.tables)
    register_compaction(spec.kind, spec.compact)
    return spec


def load_kind_module(path: str) -> KindSpec:
    """Import the module at ``path`` and register its ``SPEC``."""
    module = importlib.import_module(path)
    spec = getattr(module, "SPEC", None)
    if not isinstance(spec, KindSpec):
        raise ValueError(f"{EXTRA_KINDS_ENV}: module {path} has no SPEC (a KindSpec)")
    return register_kind(spec)


def _load() -> None:
    for name in KIND_NAMES:
        if importlib.util.find_spec(f"app.kinds.{name}") is None:
            continue  # a test asserts that every kind of the API contract is registered
        load_kind_module(f"app.kinds.{name}")
    # read from the environment, not from a Settings object: the registry is built at import, before one
    # exists (app.runtime.settings.Settings.extra_kinds documents the same variable)
    for path in os.environ.get(EXTRA_KINDS_ENV, "").split(","):
        if path.strip():
            load_kind_module(path.strip())


_load()
