"""Readers of the ``ocp`` params' single fields and sections, and the limits, for :mod:`solvers.ocp.spec`.

Each reader checks one value (an object, a list, a finite number, a unit, bounds in order) or one
section (``time``, ``transcription``, ``guess``, a list of constraints) and raises
:class:`OcpInputError` naming its path.  Standard library only, as the parser that uses them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from solvers.ocp.expressions import OcpInputError, Scope, closest
from solvers.ocp.problem import Constraint, Guess, TimeSpec, Transcription

METHODS = ("multiple_shooting", "lgl")


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


# --- parsing -------------------------------------------------------------------------------------

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


def declaration_checks(decl, path: str) -> None:
    ordered_bounds(decl.lower, decl.upper, path)
    scale = getattr(decl, "scale", None)
    if scale is not None and not scale > 0:
        raise OcpInputError(f"{path}.scale", "must be positive")
    for end in ("initial", "final"):
        v = getattr(decl, end, None)
        if v is None:
            continue
        if (decl.lower is not None and v < decl.lower) or (decl.upper is not None and v > decl.upper):
            raise OcpInputError(f"{path}.{end}", f"{end} value {v:g} outside the bounds "
                                                 f"[{decl.lower}, {decl.upper}]")


def time_spec(t: dict, path: str) -> TimeSpec:
    unknown_fields(t, ("initial", "final", "final_lower", "final_upper", "final_guess"), path)
    t0 = number_at(t.get("initial", 0.0), f"{path}.initial", optional=False)
    spec = TimeSpec(initial=t0, final=number_at(t.get("final"), f"{path}.final"),
                    final_lower=number_at(t.get("final_lower"), f"{path}.final_lower"),
                    final_upper=number_at(t.get("final_upper"), f"{path}.final_upper"),
                    final_guess=number_at(t.get("final_guess"), f"{path}.final_guess"))
    if spec.final is not None and not spec.final > t0:
        raise OcpInputError(f"{path}.final", f"final time {spec.final:g} must be after initial {t0:g}")
    if spec.final_lower is not None and spec.final_upper is not None and spec.final_lower > spec.final_upper:
        raise OcpInputError(f"{path}.final_lower", f"lower {spec.final_lower:g} > upper {spec.final_upper:g}")
    if spec.final_upper is not None and not spec.final_upper > t0:
        raise OcpInputError(f"{path}.final_upper", "must be after the initial time")
    return spec


def constraints_at(raw, path: str, scope: Scope, parse, limits: OcpLimits) -> tuple[Constraint, ...]:
    items = list_at(raw, path)
    if len(items) > limits.max_constraints:
        raise OcpInputError(path, f"{len(items)} constraints exceed the limit max_constraints={limits.max_constraints}")
    out = []
    for i, c in enumerate(items):
        cp = f"{path}.{i}"
        c = object_at(c, cp)
        unknown_fields(c, ("expr", "lower", "upper", "name"), cp)
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


def transcription_at(t: dict, path: str, limits: OcpLimits) -> Transcription:
    unknown_fields(t, ("method", "intervals", "control", "substeps", "nodes", "max_refinements", "boundaries",
                       "segment_nodes"), path)
    method = t.get("method", "multiple_shooting")
    if method not in METHODS:
        raise OcpInputError(f"{path}.method", f"'{method}' is not one of {', '.join(METHODS)}")
    control = t.get("control", "linear")
    if control not in ("linear", "constant"):
        raise OcpInputError(f"{path}.control", f"'{control}' is neither 'linear' nor 'constant'")

    def integer(key, default, lo, hi, limit=None):
        v = t.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int):
            raise OcpInputError(f"{path}.{key}", "expected an integer")
        if not lo <= v <= hi:
            lim = f" (limit {limit}={hi})" if limit and v > hi else ""
            raise OcpInputError(f"{path}.{key}", f"{v} is outside [{lo}, {hi}]{lim}")
        return v

    boundaries, segment_nodes = mesh_at(t, path, method, limits)
    intervals = integer("intervals", 50, 1, limits.max_intervals, "max_intervals")
    if boundaries is not None:          # the mesh sets the count (a preset's intervals is overridden)
        intervals = len(boundaries) - 1
    return Transcription(method=method, control=control, intervals=intervals,
                         substeps=integer("substeps", 2, 1, 16), nodes=integer("nodes", 4, 2, 12),
                         max_refinements=integer("max_refinements", 8, 0, limits.max_refinements,
                                                 "max_refinements"),
                         boundaries=boundaries, segment_nodes=segment_nodes)


def mesh_at(t: dict, path: str, method: str, limits: OcpLimits):
    """A non-uniform mesh (a refined result's ``solver.boundaries`` and ``segment_nodes``):
    interval boundaries in normalized time, 0 first, 1 last, increasing; for LGL optionally the
    nodes of each interval."""
    raw, nodes = t.get("boundaries"), t.get("segment_nodes")
    if raw is None:
        if nodes is not None:
            raise OcpInputError(f"{path}.segment_nodes", "give boundaries with segment_nodes")
        return None, None
    raw = list_at(raw, f"{path}.boundaries")
    if not 2 <= len(raw) <= limits.max_intervals + 1:
        raise OcpInputError(f"{path}.boundaries", f"{len(raw) - 1} intervals is outside [1, "
                                                  f"{limits.max_intervals}] (limit max_intervals={limits.max_intervals})")
    b = tuple(number_at(v, f"{path}.boundaries.{i}", optional=False) for i, v in enumerate(raw))
    if b[0] != 0.0 or b[-1] != 1.0 or any(y <= x for x, y in zip(b, b[1:])):
        raise OcpInputError(f"{path}.boundaries", "fractions of the horizon: 0 first, 1 last, strictly increasing")
    if nodes is None:
        return b, None
    if method != "lgl":
        raise OcpInputError(f"{path}.segment_nodes", "only for method lgl")
    nodes = list_at(nodes, f"{path}.segment_nodes")
    if len(nodes) != len(b) - 1 or any(isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= 12
                                       for n in nodes):
        raise OcpInputError(f"{path}.segment_nodes", "one integer in [2, 12] per interval")
    return b, tuple(nodes)


def guess_at(g: dict, path: str, states, controls) -> Guess:
    unknown_fields(g, ("states", "controls", "tf", "from_job"), path)

    def ends(raw, decls, key):
        declared = [d.name for d in decls]
        out = {}
        for nm, v in object_at(raw, f"{path}.{key}").items():
            vp = f"{path}.{key}.{nm}"
            if nm not in declared:
                raise OcpInputError(vp, f"'{nm}' is not a declared {key[:-1]}")
            v = list_at(v, vp)
            if len(v) != 2:
                raise OcpInputError(vp, "a guess is [first, last]")
            out[nm] = (number_at(v[0], f"{vp}.0", optional=False), number_at(v[1], f"{vp}.1", optional=False))
        return out

    from_job = g.get("from_job")
    if from_job is not None and not isinstance(from_job, str):
        raise OcpInputError(f"{path}.from_job", "a job id string")
    tf = number_at(g.get("tf"), f"{path}.tf")
    return Guess(states=ends(g.get("states"), states, "states"),
                 controls=ends(g.get("controls"), controls, "controls"), tf=tf, from_job=from_job)
