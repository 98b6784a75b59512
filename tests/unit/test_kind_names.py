"""A kind is declared once, in its KindSpec, and asked, never listed: no module outside its package
(``app/kinds/<kind>/``) and the registry (``app/kinds/__init__.py``) names a kind.

"Names" means, in Python (``app/``, ``worker/``), a string constant equal to a kind's name (a dict key,
a comparison, a tuple member) or an import of a kind's package (``app.kinds.<kind>``, ``solvers.<kind>``);
in the console's scripts and templates (``app/web/``), a quoted string equal to a kind's name.  Prose in
docstrings and comments is not a name: it documents, nothing dispatches on it.  Each check also runs on a
planted violation, so it is shown to fail.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from app.kinds import KIND_NAMES, KINDS

ROOT = Path(__file__).resolve().parents[2]
NAMES = frozenset(KIND_NAMES) | frozenset(KINDS)

# Where a kind's name is data, not dispatch: file -> (names allowed there, why).
ALLOWED: dict[str, tuple[frozenset[str], str]] = {
    "app/api/submit_examples.py": (frozenset({"reentry", "ocp"}),
                                   "the documented request examples of POST /v1/jobs in OpenAPI (a body names its kind)"),
    "app/api/routes/studies.py": (frozenset({"reentry"}),
                                  "the documented request examples of POST /v1/studies in OpenAPI"),
    "app/service/study_presets.py": (frozenset({"reentry", "robust_reentry", "midcourse", "intercept"}),
                                     "the named studies: each is a request body naming the kind it sweeps"),
    "app/api/routes/vehicles.py": (frozenset({"reentry"}),
                                   "GET /v1/vehicles serves the reentry kind's vehicle catalogue "
                                   "(app.kinds.reentry.vehicle): a route a kind adds, which KindSpec does not carry"),
}


def _owner(rel: str) -> str | None:
    """The kind whose package holds ``rel``, or "registry", or None for shared code."""
    parts = rel.split("/")
    if parts[:2] == ["app", "kinds"]:
        if len(parts) > 3 and parts[2] in NAMES:
            return parts[2]
        if parts[2] == "__init__.py":
            return "registry"
    return None


def python_names(source: str) -> set[str]:
    """The kind names a Python module's code uses: string constants and imported kind packages."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in NAMES:
            found.add(node.value)
        modules = []
        if isinstance(node, ast.Import):
            modules = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            modules = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        for module in modules:
            parts = module.split(".")
            if parts[:2] == ["app", "kinds"] and len(parts) > 2 and parts[2] in NAMES:
                found.add(parts[2])
            if parts[0] == "solvers" and len(parts) > 1 and parts[1] in NAMES:
                found.add(parts[1])
    return found


_QUOTED = re.compile(r"""(["'`])([a-z_]+)\1""")


def script_names(text: str) -> set[str]:
    """The kind names quoted in a script or template (``job.kind === "midcourse"``, ``{'ocp': ...}``)."""
    return {m.group(2) for m in _QUOTED.finditer(text) if m.group(2) in NAMES}


def _sources():
    for top in ("app", "worker"):
        for path in sorted((ROOT / top).rglob("*.py")):
            yield path.relative_to(ROOT).as_posix(), python_names(path.read_text())
    # the console's own scripts and templates; app/static/docs holds the vendored Swagger UI and ReDoc bundles
    for pattern in ("*.js", "*.html"):
        for path in sorted((ROOT / "app" / "web").rglob(pattern)):
            yield path.relative_to(ROOT).as_posix(), script_names(path.read_text())


def test_no_module_outside_the_kind_packages_and_the_registry_names_a_kind():
    offenders = {}
    for rel, names in _sources():
        if _owner(rel) is not None:
            continue
        allowed = ALLOWED.get(rel, (frozenset(), ""))[0]
        if names - allowed:
            offenders[rel] = sorted(names - allowed)
    assert not offenders, ("shared code names kinds (ask the KindSpec instead: docs/architecture.md "
                           f"'How to add a kind'): {offenders}")


def test_every_allowed_entry_is_still_needed():
    """An allow-list entry whose file no longer names the kinds it lists is stale: it goes."""
    found = dict(_sources())
    for rel, (names, reason) in ALLOWED.items():
        assert reason and rel in found, rel
        assert names <= found[rel], f"{rel} no longer names {sorted(names - found[rel])}: shrink ALLOWED"


@pytest.mark.parametrize("source, names", [
    ('if job.kind == "midcourse":\n    pass\n', {"midcourse"}),
    ('COST = {"reentry": 1.0, "robust_reentry": 2.0}\n', {"reentry", "robust_reentry"}),
    ("from app.kinds.intercept.oem import to_oem\n", {"intercept"}),
    ("from app.kinds import ocp\n", {"ocp"}),
    ("import solvers.midcourse.cases\n", {"midcourse"}),
    ('"""Docstrings may speak of the reentry kind."""\nx = "reentry kind"\n', set()),
])
def test_the_python_scan_finds_a_planted_name(source, names):
    assert python_names(source) == names


@pytest.mark.parametrize("text, names", [
    ('if (job.kind === "midcourse") await frontTable(id, job);', {"midcourse"}),
    ("{% if kind == 'ocp' %}", {"ocp"}),
    ("// for a midcourse job, the table of its front", set()),
])
def test_the_script_scan_finds_a_planted_name(text, names):
    assert script_names(text) == names


def test_the_registry_and_a_kind_package_are_exempt_and_shared_code_is_not():
    assert _owner("app/kinds/__init__.py") == "registry"
    assert _owner("app/kinds/midcourse/oem.py") == "midcourse"
    assert _owner("app/kinds/base.py") is None
    assert _owner("app/results/tables.py") is None
