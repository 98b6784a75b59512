"""The ``ocp`` problem as data: the spec's ``params`` object -> validated, typed, frozen dataclasses.

:func:`parse_problem` checks everything ``../shared/specs/ocp.md`` lists under "Errors" and raises
:class:`OcpInputError` (``path``: the field, as ``params.dynamics.v``; ``reason``: why) at the
first problem found; what it returns can be built.  Expressions become trees of
:mod:`solvers.ocp.expressions`.  Standard library only: the API process validates with it before
it stores a job, and loads no numpy or CasADi for that.  The dataclasses live in
:mod:`solvers.ocp.problem` and are re-exported here.
"""
from __future__ import annotations

import keyword
import math
import re
from dataclasses import dataclass

from solvers.ocp.expressions import (
    FUNCTIONS,
    RESERVED,
    OcpInputError,
    Scope,
    closest,
    names_used,
    parse_expression,
)
from solvers.ocp.problem import (
    Constraint,
    ControlDecl,
    Guess,
    Objective,
    OcpProblem,
    ParameterDecl,
    Phase,
    StateDecl,
    TableDecl,
    TimeSpec,
    Transcription,
    VariableDecl,
)

__all__ = [
    "Constraint",
    "ControlDecl",
    "Guess",
    "Objective",
    "OcpInputError",
    "OcpLimits",
    "OcpProblem",
    "ParameterDecl",
    "Phase",
    "StateDecl",
    "TableDecl",
    "TimeSpec",
    "Transcription",
    "VariableDecl",
    "parse_problem",
]

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
TOP_FIELDS = ("title", "constants", "tables", "states", "controls", "parameters", "time",
              "expressions", "dynamics", "path", "boundary", "objective", "transcription", "guess",
              "accuracy", "plots")
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


# --- parsing -------------------------------------------------------------------------------------
def _obj(value, path: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise OcpInputError(path, f"expected an object, not {type(value).__name__}")
    return value


def _list(value, path: str) -> list:
    if value is None:
        return []
    if not isinstance(value, list):
        raise OcpInputError(path, f"expected a list, not {type(value).__name__}")
    return value


def _number(value, path: str, *, optional: bool = True) -> float | None:
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


def _unknown_fields(d: dict, allowed, path: str) -> None:
    for k in d:
        if k not in allowed:
            hint = closest(str(k), allowed)
            raise OcpInputError(f"{path}.{k}", "unknown field" + (f"; did you mean '{hint}'?" if hint else ""))


def _bounds(lo, hi, path: str) -> None:
    if lo is not None and hi is not None and lo > hi:
        raise OcpInputError(f"{path}.lower", f"lower {lo:g} > upper {hi:g}")


class _Names:
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
        if name in FUNCTIONS:
            raise OcpInputError(path, f"'{name}' shadows the function {name}()")
        if name in self.kinds or (name in self.tables and kind != "table"):
            other = "table" if name in self.tables else self.kinds[name]
            raise OcpInputError(path, f"duplicated name '{name}' (already a {other})")
        if kind != "table":
            self.kinds[name] = kind
        return name


def parse_problem(params: dict, limits: OcpLimits = OcpLimits()) -> OcpProblem:
    """Validate the spec's ``params`` object and return the problem; :class:`OcpInputError` otherwise."""
    P = "params"
    if not isinstance(params, dict):
        raise OcpInputError(P, "expected an object")
    if "phases" in params:
        raise OcpInputError(f"{P}.phases", "several phases are not supported yet; pose a single phase")
    _unknown_fields(params, TOP_FIELDS, P)
    title = params.get("title") or ""
    if not isinstance(title, str) or len(title) > 500:
        raise OcpInputError(f"{P}.title", "a string of at most 500 characters")

    # tables first: their names are callable in every expression
    tables_raw = _obj(params.get("tables"), f"{P}.tables")
    if len(tables_raw) > limits.max_tables:
        raise OcpInputError(f"{P}.tables", f"{len(tables_raw)} tables exceed the limit max_tables={limits.max_tables}")
    table_dims: dict[str, int] = {}
    names = _Names(table_dims)
    tables = []
    total_values = 0
    for tname, tdef in tables_raw.items():
        tp = f"{P}.tables.{tname}"
        names.declare(tname, "table", tp)
        tdef = _obj(tdef, tp)
        _unknown_fields(tdef, ("axes", "values"), tp)
        axes_raw = _list(tdef.get("axes"), f"{tp}.axes")
        if len(axes_raw) not in (1, 2):
            raise OcpInputError(f"{tp}.axes", f"a table has 1 or 2 axes, not {len(axes_raw)}")
        axes = []
        for i, ax in enumerate(axes_raw):
            ap = f"{tp}.axes.{i}"
            ax = _list(ax, ap)
            if len(ax) < 2:
                raise OcpInputError(ap, "an axis needs at least 2 points")
            total_values += len(ax)
            if total_values > limits.max_table_values:
                raise OcpInputError(ap, f"tables exceed the limit max_table_values={limits.max_table_values}")
            vals = tuple(_number(v, f"{ap}.{j}", optional=False) for j, v in enumerate(ax))
            for j in range(1, len(vals)):
                if not vals[j] > vals[j - 1]:
                    raise OcpInputError(f"{ap}.{j}", f"axis not strictly increasing ({vals[j - 1]:g} then {vals[j]:g})")
            axes.append(vals)
        values_raw = _list(tdef.get("values"), f"{tp}.values")
        need = math.prod(len(a) for a in axes)
        if len(values_raw) != need:
            raise OcpInputError(f"{tp}.values", f"{len(values_raw)} values, the axes need "
                                                f"{' x '.join(str(len(a)) for a in axes)} = {need} (row-major)")
        total_values += need
        if total_values > limits.max_table_values:
            raise OcpInputError(f"{tp}.values", f"tables exceed the limit max_table_values={limits.max_table_values}")
        values = tuple(_number(v, f"{tp}.values.{j}", optional=False) for j, v in enumerate(values_raw))
        table_dims[tname] = len(axes)
        tables.append(TableDecl(tname, tuple(axes), values))

    constants = []
    for cname, cval in _obj(params.get("constants"), f"{P}.constants").items():
        cp = f"{P}.constants.{cname}"
        names.declare(cname, "constant", cp)
        constants.append((cname, _number(cval, cp, optional=False)))

    states = _declarations(params, "states", names, limits)
    if not states:
        raise OcpInputError(f"{P}.states", "at least one state is required")
    controls = _declarations(params, "controls", names, limits)
    parameters = _declarations(params, "parameters", names, limits)

    time = _time(_obj(params.get("time"), f"{P}.time"), f"{P}.time")

    def parse(text, path, scope):
        return parse_expression(text, path=path, scope=scope, max_chars=limits.max_expression_chars,
                                max_nodes=limits.max_expression_nodes)

    # named expressions: each sees what is declared plus the expressions before it
    exprs_raw = _obj(params.get("expressions"), f"{P}.expressions")
    if len(exprs_raw) > limits.max_expressions:
        raise OcpInputError(f"{P}.expressions", f"{len(exprs_raw)} expressions exceed the limit "
                                                f"max_expressions={limits.max_expressions}")
    base = {**names.kinds, "t": "time", "t0": "time", "tf": "time"}
    expressions = []
    for ename, etext in exprs_raw.items():
        ep = f"{P}.expressions.{ename}"
        names.declare(ename, "expression", ep)
        scope = Scope({**base, **{n: "expression" for n, _ in expressions}}, table_dims,
                      where="expressions")
        expressions.append((ename, parse(etext, ep, scope)))
    along = Scope({**base, **{n: "expression" for n, _ in expressions}}, table_dims)

    dyn_raw = _obj(params.get("dynamics"), f"{P}.dynamics")
    state_names = [s.name for s in states]
    for k in dyn_raw:
        if k not in state_names:
            hint = closest(str(k), state_names)
            raise OcpInputError(f"{P}.dynamics.{k}", f"dynamics for '{k}', which is not a declared state"
                                + (f"; did you mean '{hint}'?" if hint else ""))
    dynamics = []
    for i, s in enumerate(states):
        if s.name not in dyn_raw:
            raise OcpInputError(f"{P}.dynamics", f"state '{s.name}' has no dynamics (params.states.{i})")
        dynamics.append(parse(dyn_raw[s.name], f"{P}.dynamics.{s.name}",
                              Scope(along.names, table_dims, where="dynamics")))

    path_scope = Scope(along.names, table_dims, where="a path constraint")
    event_names = {n: k for n, k in base.items() if k != "time" or n in ("t0", "tf")}
    event_scope = Scope(event_names, table_dims, boundary=True, where="a boundary constraint")
    path = _constraints(params.get("path"), f"{P}.path", path_scope, parse, limits)
    boundary = _constraints(params.get("boundary"), f"{P}.boundary", event_scope, parse, limits)

    op = f"{P}.objective"
    obj_raw = _obj(params.get("objective"), op)
    if not obj_raw:
        raise OcpInputError(op, "an objective is required: {\"sense\", \"expr\"?, \"integrand\"?}")
    _unknown_fields(obj_raw, ("sense", "expr", "integrand"), op)
    sense = obj_raw.get("sense", "minimize")
    if sense not in ("minimize", "maximize"):
        raise OcpInputError(f"{op}.sense", f"'{sense}' is neither 'minimize' nor 'maximize'")
    if obj_raw.get("expr") is None and obj_raw.get("integrand") is None:
        raise OcpInputError(op, "give expr (Mayer term), integrand (Lagrange term) or both")
    objective = Objective(
        sense=sense,
        expr=None if obj_raw.get("expr") is None else parse(
            obj_raw["expr"], f"{op}.expr", Scope(event_names, table_dims, boundary=True, where="the objective's expr")),
        integrand=None if obj_raw.get("integrand") is None else parse(
            obj_raw["integrand"], f"{op}.integrand", Scope(along.names, table_dims, where="the objective's integrand")),
        expr_text=str(obj_raw.get("expr") or ""), integrand_text=str(obj_raw.get("integrand") or ""))

    transcription = _transcription(_obj(params.get("transcription"), f"{P}.transcription"),
                                   f"{P}.transcription", limits)
    guess = _guess(_obj(params.get("guess"), f"{P}.guess"), f"{P}.guess", states, controls)
    accuracy = _number(params.get("accuracy"), f"{P}.accuracy")
    if accuracy is not None and not accuracy > 0:
        raise OcpInputError(f"{P}.accuracy", "must be positive")
    plots = []
    reportable = {"t", *names.kinds}
    for i, pair in enumerate(_list(params.get("plots"), f"{P}.plots")):
        pp = f"{P}.plots.{i}"
        pair = _list(pair, pp)
        if len(pair) != 2:
            raise OcpInputError(pp, "a plot is a pair of names [x, y]")
        for j, nm in enumerate(pair):
            if nm not in reportable or names.kinds.get(nm) in ("constant", "parameter"):
                raise OcpInputError(f"{pp}.{j}", f"'{nm}' is not a state, control, expression or t")
        plots.append((pair[0], pair[1]))

    phase = Phase(states=tuple(states), controls=tuple(controls), time=time,
                  expressions=tuple(expressions), dynamics=tuple(dynamics), path=path,
                  boundary=boundary, transcription=transcription, guess=guess)
    return OcpProblem(title=title, constants=tuple(constants), tables=tuple(tables),
                      parameters=tuple(parameters), phase=phase, objective=objective,
                      accuracy=accuracy, plots=tuple(plots))


# field -> (class, kind of name, its number fields, whether it has a unit, its limit)
_DECLARATIONS = {
    "states": (StateDecl, "state", ("initial", "final", "lower", "upper", "scale"), True, "max_states"),
    "controls": (ControlDecl, "control", ("lower", "upper", "scale"), True, "max_controls"),
    "parameters": (ParameterDecl, "parameter", ("lower", "upper", "guess"), False, "max_parameters"),
}


def _declarations(params: dict, field: str, names: _Names, limits: OcpLimits) -> list:
    """The declared states, controls or parameters, in order, their names entered in ``names``."""
    cls, kind, numbers, has_unit, limit = _DECLARATIONS[field]
    path = f"params.{field}"
    raw = _list(params.get(field), path)
    cap = getattr(limits, limit)
    if len(raw) > cap:
        raise OcpInputError(path, f"{len(raw)} {field} exceed the limit {limit}={cap}")
    out = []
    for i, d in enumerate(raw):
        dp = f"{path}.{i}"
        d = _obj(d, dp)
        _unknown_fields(d, ("name", *numbers, *(("unit",) if has_unit else ())), dp)
        extra = {"unit": _unit(d.get("unit"), f"{dp}.unit")} if has_unit else {}
        decl = cls(name=names.declare(d.get("name"), kind, f"{dp}.name"),
                   **{k: _number(d.get(k), f"{dp}.{k}") for k in numbers}, **extra)
        _decl_checks(decl, dp)
        out.append(decl)
    return out


def _unit(value, path: str) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or len(value) > 40:
        raise OcpInputError(path, "a unit is a string of at most 40 characters")
    return value


def _decl_checks(decl, path: str) -> None:
    _bounds(decl.lower, decl.upper, path)
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


def _time(t: dict, path: str) -> TimeSpec:
    _unknown_fields(t, ("initial", "final", "final_lower", "final_upper", "final_guess"), path)
    t0 = _number(t.get("initial", 0.0), f"{path}.initial", optional=False)
    spec = TimeSpec(initial=t0, final=_number(t.get("final"), f"{path}.final"),
                    final_lower=_number(t.get("final_lower"), f"{path}.final_lower"),
                    final_upper=_number(t.get("final_upper"), f"{path}.final_upper"),
                    final_guess=_number(t.get("final_guess"), f"{path}.final_guess"))
    if spec.final is not None and not spec.final > t0:
        raise OcpInputError(f"{path}.final", f"final time {spec.final:g} must be after initial {t0:g}")
    if spec.final_lower is not None and spec.final_upper is not None and spec.final_lower > spec.final_upper:
        raise OcpInputError(f"{path}.final_lower", f"lower {spec.final_lower:g} > upper {spec.final_upper:g}")
    if spec.final_upper is not None and not spec.final_upper > t0:
        raise OcpInputError(f"{path}.final_upper", "must be after the initial time")
    return spec


def _constraints(raw, path: str, scope: Scope, parse, limits: OcpLimits) -> tuple[Constraint, ...]:
    items = _list(raw, path)
    if len(items) > limits.max_constraints:
        raise OcpInputError(path, f"{len(items)} constraints exceed the limit max_constraints={limits.max_constraints}")
    out = []
    for i, c in enumerate(items):
        cp = f"{path}.{i}"
        c = _obj(c, cp)
        _unknown_fields(c, ("expr", "lower", "upper", "name"), cp)
        if "expr" not in c:
            raise OcpInputError(f"{cp}.expr", "an expression is required")
        lo, hi = _number(c.get("lower"), f"{cp}.lower"), _number(c.get("upper"), f"{cp}.upper")
        if lo is None and hi is None:
            raise OcpInputError(cp, "give lower, upper or both")
        _bounds(lo, hi, cp)
        name = c.get("name") or f"{path.rsplit('.', 1)[-1]}_{i}"
        if not isinstance(name, str) or len(name) > 64:
            raise OcpInputError(f"{cp}.name", "a string of at most 64 characters")
        out.append(Constraint(expr=parse(c["expr"], f"{cp}.expr", scope), text=str(c["expr"]),
                              lower=lo, upper=hi, name=name))
    return tuple(out)


def _transcription(t: dict, path: str, limits: OcpLimits) -> Transcription:
    _unknown_fields(t, ("method", "intervals", "control", "substeps", "nodes", "max_refinements"), path)
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

    integer("max_refinements", 8, 0, 20)
    return Transcription(method=method, control=control,
                         intervals=integer("intervals", 50, 1, limits.max_intervals, "max_intervals"),
                         substeps=integer("substeps", 2, 1, 16), nodes=integer("nodes", 4, 2, 12))


def _guess(g: dict, path: str, states, controls) -> Guess:
    _unknown_fields(g, ("states", "controls", "tf", "from_job"), path)

    def ends(raw, decls, key):
        declared = [d.name for d in decls]
        out = {}
        for nm, v in _obj(raw, f"{path}.{key}").items():
            vp = f"{path}.{key}.{nm}"
            if nm not in declared:
                raise OcpInputError(vp, f"'{nm}' is not a declared {key[:-1]}")
            v = _list(v, vp)
            if len(v) != 2:
                raise OcpInputError(vp, "a guess is [first, last]")
            out[nm] = (_number(v[0], f"{vp}.0", optional=False), _number(v[1], f"{vp}.1", optional=False))
        return out

    from_job = g.get("from_job")
    if from_job is not None and not isinstance(from_job, str):
        raise OcpInputError(f"{path}.from_job", "a job id string")
    tf = _number(g.get("tf"), f"{path}.tf")
    return Guess(states=ends(g.get("states"), states, "states"),
                 controls=ends(g.get("controls"), controls, "controls"), tf=tf, from_job=from_job)


def referenced_names(problem: OcpProblem) -> set[str]:
    """Every name some expression of the problem uses (to warn about unused declarations)."""
    trees = [e for _, e in problem.expressions] + list(problem.dynamics)
    trees += [c.expr for c in problem.path + problem.boundary]
    trees += [e for e in (problem.objective.expr, problem.objective.integrand) if e is not None]
    out: set[str] = set()
    for e in trees:
        out |= names_used(e)
    return out
