"""Readers of single values of the ``ocp`` params, the namespace of declared names, and the size limits.

Each reader checks one value (an object, a list, a finite number, a unit, bounds in order) and
raises :class:`OcpInputError` naming its path; :class:`Names` keeps the declared names of one
namespace unique and clear of the language's own; :class:`OcpLimits` are the service's size
limits.  Used by the problem's parser (:mod:`solvers.ocp.spec`) and a phase's
(:mod:`solvers.ocp.phase_spec`).  Standard library only.
"""
from __future__ import annotations

import keyword
import math
import re
from dataclasses import dataclass
from typing import Literal, overload

from solvers.ocp.expressions import FUNCTIONS, RESERVED, OcpInputError, Scope, closest, parse_expression
from solvers.ocp.problem import Constraint
from solvers.ocp.shape import FIELDS

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


@dataclass(frozen=True)
class OcpLimits:
    """The size limits of one problem (service settings; a problem past them is a 422 naming the limit)."""

    max_expression_chars: int = 2000
    max_expression_nodes: int = 400
    max_states: int = 50
    max_controls: int = 20
    max_parameters: int = 20
    max_expressions: int = 200
    max_tables: int = 50
    max_table_values: int = 100_000
    max_intervals: int = 1000
    max_constraints: int = 200
    max_refinements: int = 20          # transcription.max_refinements (mesh-refinement rounds)
    max_starts: int = 16               # search.starts (initial guesses, each a solve)
    max_monte_carlo_samples: int = 100_000   # robust.monte_carlo.samples


def expression_parser(limits: OcpLimits):
    """``parse(text, path, scope)``: an expression of the language within the limits."""
    def parse(text, path, scope):
        return parse_expression(text, path=path, scope=scope, max_chars=limits.max_expression_chars,
                                max_nodes=limits.max_expression_nodes)
    return parse


class Names:
    """Every declared name in one namespace: unique, an identifier, shadowing nothing."""

    def __init__(self, tables: dict[str, int]):
        self.kinds: dict[str, str] = {}
        self.tables = tables

    def declare(self, name, kind: str, path: str) -> str:
        if not isinstance(name, str) or not name:
            raise OcpInputError(path, "a name must be a non-empty string")
        if not _IDENT.match(name) or len(name) > 64:
            raise OcpInputError(path, f"'{name[:64]}' is not a valid name (letters, digits, _; "
                                      "not starting with a digit; at most 64 characters)")
        if keyword.iskeyword(name) or keyword.issoftkeyword(name):
            raise OcpInputError(path, f"'{name}' is a Python keyword and cannot be a name")
        if name in RESERVED:
            raise OcpInputError(path, f"'{name}' is reserved ({', '.join(RESERVED)})")
        if name.startswith("_"):   # Python's own names (__class__) and the parser's helpers live there
            raise OcpInputError(path, f"'{name}' is reserved: a name cannot begin with an underscore")
        if name in FUNCTIONS:
            raise OcpInputError(path, f"'{name}' shadows the function {name}()")
        if name in self.kinds or (name in self.tables and kind != "table"):
            other = "table" if name in self.tables else self.kinds[name]
            raise OcpInputError(path, f"duplicated name '{name}' (already a {other})")
        if kind != "table":
            self.kinds[name] = kind
        return name

    def copy(self) -> Names:
        """A namespace that starts with these names (a phase's, over the problem's)."""
        out = Names(self.tables)
        out.kinds = dict(self.kinds)
        return out


def object_at(value, path: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise OcpInputError(path, f"expected an object, not {type(value).__name__}")
    return value


def list_at(value, path: str) -> list:
    if value is None:
        return []
    if not isinstance(value, list):
        raise OcpInputError(path, f"expected a list, not {type(value).__name__}")
    return value


@overload
def number_at(value, path: str, *, optional: Literal[False]) -> float: ...


@overload
def number_at(value, path: str, *, optional: bool = True) -> float | None: ...


def number_at(value, path: str, *, optional: bool = True) -> float | None:
    if value is None:
        if optional:
            return None
        raise OcpInputError(path, "a number is required")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise OcpInputError(path, f"expected a number, not {type(value).__name__}")
    try:
        f = float(value)
    except OverflowError:
        f = math.inf
    if not math.isfinite(f):
        raise OcpInputError(path, "must be finite")
    return f


def unknown_fields(d: dict, allowed, path: str) -> None:
    for k in d:
        if k not in allowed:
            hint = closest(str(k), allowed)
            raise OcpInputError(f"{path}.{k}", "unknown field" + (f"; did you mean '{hint}'?" if hint else ""))


def ordered_bounds(lo, hi, path: str) -> None:
    if lo is not None and hi is not None and lo > hi:
        raise OcpInputError(f"{path}.lower", f"lower {lo:g} > upper {hi:g}")


def unit_at(value, path: str) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or len(value) > 40:
        raise OcpInputError(path, "a unit is a string of at most 40 characters")
    return value


def constraints_at(raw, path: str, scope: Scope, parse, limits: OcpLimits) -> tuple[Constraint, ...]:
    items = list_at(raw, path)
    if len(items) > limits.max_constraints:
        raise OcpInputError(path, f"{len(items)} constraints exceed the limit max_constraints={limits.max_constraints}")
    out = []
    for i, c in enumerate(items):
        cp = f"{path}.{i}"
        c = object_at(c, cp)
        unknown_fields(c, FIELDS["constraint"], cp)
        if "expr" not in c:
            raise OcpInputError(f"{cp}.expr", "an expression is required")
        lo, hi = number_at(c.get("lower"), f"{cp}.lower"), number_at(c.get("upper"), f"{cp}.upper")
        if lo is None and hi is None:
            raise OcpInputError(cp, "give lower, upper or both")
        ordered_bounds(lo, hi, cp)
        name = c.get("name") or f"{path.rsplit('.', 1)[-1]}_{i}"
        if not isinstance(name, str) or len(name) > 64:
            raise OcpInputError(f"{cp}.name", "a string of at most 64 characters")
        out.append(Constraint(expr=parse(c["expr"], f"{cp}.expr", scope), text=str(c["expr"]),
                              lower=lo, upper=hi, name=name))
    return tuple(out)
