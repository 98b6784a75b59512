"""Lazy public faces for the kind packages (PEP 562).

A kind package's ``__init__`` names its problem, solution and ``solve``, but importing it must stay
light: the API process imports ``solvers.<kind>.cases`` (numpy-free) and so runs the package's
``__init__``, and it must not load CasADi, heyoka or pymoo (tests/unit/test_layering.py). So the
``__init__`` declares which submodule holds each public name and imports it on first use.
"""
from __future__ import annotations

import importlib
import sys
from typing import Callable


def lazy_exports(package: str, exports: dict[str, str]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package``, where ``exports`` maps each public name to the
    submodule (relative to ``package``) that defines it; a name is imported once, then cached."""
    def __getattr__(name: str) -> object:
        try:
            submodule = exports[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(f"{package}.{submodule}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(exports) | set(vars(sys.modules[package])))

    return __getattr__, __dir__
