"""The ``ocp`` problem as data: the spec's ``params`` object -> validated, typed, frozen dataclasses.

:func:`parse_problem` checks everything ``../shared/specs/ocp.md`` lists under "Errors" and raises
:class:`OcpInputError` (``path``: the field, as ``params.dynamics.v``; ``reason``: why) at the
first problem found; what it returns can be built.  Expressions become trees of
:mod:`solvers.ocp.expressions`.  Standard library only: the API process validates with it before
it stores a job, and loads no numpy or CasADi for that.  The dataclasses live in
:mod:`solvers.ocp.problem` and are re-exported here; the readers of single fields and sections
(and :class:`OcpLimits`) in :mod:`solvers.ocp.fields`.
"""
from __future__ import annotations

import keyword
import math
import re

from solvers.ocp.expressions import (
    FUNCTIONS,
    RESERVED,
    OcpInputError,
    Scope,
    closest,
    names_used,
    parse_expression,
)
from solvers.ocp.fields import (
    OcpLimits,
    constraints_at,
    declaration_checks,
    guess_at,
    list_at,
    number_at,
    object_at,
    time_spec,
    transcription_at,
    unit_at,
    unknown_fields,
)
from solvers.ocp.problem import (
    Constraint,
    ControlDecl,
    Guess,
    NamedPhase,
    Objective,
    OcpProblem,
    ParameterDecl,
    Phase,
    PhaseProblem,
    PhaseTime,
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
              "accuracy", "accuracy_required", "plots")

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


def parse_problem(params: dict, limits: OcpLimits = OcpLimits()) -> OcpProblem:
    """Validate the spec's ``params`` object and return the problem; :class:`OcpInputError` otherwise."""
    if not isinstance(params, dict):
        raise OcpInputError("params", "expected an object")
    if params.get("phases") is not None:     # several phases: solvers.ocp.phases_spec (which parses each phase here)
        from solvers.ocp.phases_spec import parse_phases
        return parse_phases(params, limits, parse_phase_problem)
    one = parse_phase_problem(params, limits)
    t = one.phase.time
    window = PhaseTime(initial=t.initial, final=t.final, final_lower=t.final_lower, final_upper=t.final_upper,
                       final_guess=t.final_guess)
    return OcpProblem(title=one.title, constants=one.constants, tables=one.tables, parameters=one.parameters,
                      phases=(NamedPhase("", window, one),), objective=one.objective,
                      from_job=one.phase.guess.from_job, plots=one.plots, accuracy=one.accuracy,
                      accuracy_required=one.accuracy_required, single=True)


def parse_phase_problem(params: dict, limits: OcpLimits = OcpLimits()) -> PhaseProblem:
    P = "params"
    if not isinstance(params, dict):
        raise OcpInputError(P, "expected an object")
    unknown_fields(params, TOP_FIELDS, P)
    title = params.get("title") or ""
    if not isinstance(title, str) or len(title) > 500:
        raise OcpInputError(f"{P}.title", "a string of at most 500 characters")

    # tables first: their names are callable in every expression
    tables_raw = object_at(params.get("tables"), f"{P}.tables")
    if len(tables_raw) > limits.max_tables:
        raise OcpInputError(f"{P}.tables", f"{len(tables_raw)} tables exceed the limit max_tables={limits.max_tables}")
    table_dims: dict[str, int] = {}
    names = _Names(table_dims)
    tables = []
    total_values = 0
    for tname, tdef in tables_raw.items():
        tp = f"{P}.tables.{tname}"
        names.declare(tname, "table", tp)
        tdef = object_at(tdef, tp)
        unknown_fields(tdef, ("axes", "values"), tp)
        axes_raw = list_at(tdef.get("axes"), f"{tp}.axes")
        if len(axes_raw) not in (1, 2):
            raise OcpInputError(f"{tp}.axes", f"a table has 1 or 2 axes, not {len(axes_raw)}")
        axes = []
        for i, ax in enumerate(axes_raw):
            ap = f"{tp}.axes.{i}"
            ax = list_at(ax, ap)
            if len(ax) < 2:
                raise OcpInputError(ap, "an axis needs at least 2 points")
            total_values += len(ax)
            if total_values > limits.max_table_values:
                raise OcpInputError(ap, f"tables exceed the limit max_table_values={limits.max_table_values}")
            vals = tuple(number_at(v, f"{ap}.{j}", optional=False) for j, v in enumerate(ax))
            for j in range(1, len(vals)):
                if not vals[j] > vals[j - 1]:
                    raise OcpInputError(f"{ap}.{j}", f"axis not strictly increasing ({vals[j - 1]:g} then {vals[j]:g})")
            axes.append(vals)
        values_raw = list_at(tdef.get("values"), f"{tp}.values")
        need = math.prod(len(a) for a in axes)
        if len(values_raw) != need:
            raise OcpInputError(f"{tp}.values", f"{len(values_raw)} values, the axes need "
                                                f"{' x '.join(str(len(a)) for a in axes)} = {need} (row-major)")
        total_values += need
        if total_values > limits.max_table_values:
            raise OcpInputError(f"{tp}.values", f"tables exceed the limit max_table_values={limits.max_table_values}")
        values = tuple(number_at(v, f"{tp}.values.{j}", optional=False) for j, v in enumerate(values_raw))
        table_dims[tname] = len(axes)
        tables.append(TableDecl(tname, tuple(axes), values))

    constants = []
    for cname, cval in object_at(params.get("constants"), f"{P}.constants").items():
        cp = f"{P}.constants.{cname}"
        names.declare(cname, "constant", cp)
        constants.append((cname, number_at(cval, cp, optional=False)))

    states = _declarations(params, "states", names, limits)
    if not states:
        raise OcpInputError(f"{P}.states", "at least one state is required")
    controls = _declarations(params, "controls", names, limits)
    parameters = _declarations(params, "parameters", names, limits)

    time = time_spec(object_at(params.get("time"), f"{P}.time"), f"{P}.time")

    def parse(text, path, scope):
        return parse_expression(text, path=path, scope=scope, max_chars=limits.max_expression_chars,
                                max_nodes=limits.max_expression_nodes)

    # named expressions: each sees what is declared plus the expressions before it
    exprs_raw = object_at(params.get("expressions"), f"{P}.expressions")
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

    dyn_raw = object_at(params.get("dynamics"), f"{P}.dynamics")
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
    path = constraints_at(params.get("path"), f"{P}.path", path_scope, parse, limits)
    boundary = constraints_at(params.get("boundary"), f"{P}.boundary", event_scope, parse, limits)

    op = f"{P}.objective"
    obj_raw = object_at(params.get("objective"), op)
    if not obj_raw:
        raise OcpInputError(op, "an objective is required: {\"sense\", \"expr\"?, \"integrand\"?}")
    unknown_fields(obj_raw, ("sense", "expr", "integrand"), op)
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

    transcription = transcription_at(object_at(params.get("transcription"), f"{P}.transcription"),
                                   f"{P}.transcription", limits)
    guess = guess_at(object_at(params.get("guess"), f"{P}.guess"), f"{P}.guess", states, controls)
    accuracy = number_at(params.get("accuracy"), f"{P}.accuracy")
    if accuracy is not None and not accuracy > 0:
        raise OcpInputError(f"{P}.accuracy", "must be positive")
    accuracy_required = params.get("accuracy_required", True)
    if not isinstance(accuracy_required, bool):
        raise OcpInputError(f"{P}.accuracy_required", "expected true or false")
    plots = []
    reportable = {"t", *names.kinds}
    for i, pair in enumerate(list_at(params.get("plots"), f"{P}.plots")):
        pp = f"{P}.plots.{i}"
        pair = list_at(pair, pp)
        if len(pair) != 2:
            raise OcpInputError(pp, "a plot is a pair of names [x, y]")
        for j, nm in enumerate(pair):
            if nm not in reportable or names.kinds.get(nm) in ("constant", "parameter"):
                raise OcpInputError(f"{pp}.{j}", f"'{nm}' is not a state, control, expression or t")
        plots.append((pair[0], pair[1]))

    phase = Phase(states=tuple(states), controls=tuple(controls), time=time,
                  expressions=tuple(expressions), dynamics=tuple(dynamics), path=path,
                  boundary=boundary, transcription=transcription, guess=guess)
    return PhaseProblem(title=title, constants=tuple(constants), tables=tuple(tables),
                      parameters=tuple(parameters), phase=phase, objective=objective,
                      accuracy=accuracy, accuracy_required=accuracy_required, plots=tuple(plots))


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
    raw = list_at(params.get(field), path)
    cap = getattr(limits, limit)
    if len(raw) > cap:
        raise OcpInputError(path, f"{len(raw)} {field} exceed the limit {limit}={cap}")
    out = []
    for i, d in enumerate(raw):
        dp = f"{path}.{i}"
        d = object_at(d, dp)
        unknown_fields(d, ("name", *numbers, *(("unit",) if has_unit else ())), dp)
        extra = {"unit": unit_at(d.get("unit"), f"{dp}.unit")} if has_unit else {}
        decl = cls(name=names.declare(d.get("name"), kind, f"{dp}.name"),
                   **{k: number_at(d.get(k), f"{dp}.{k}") for k in numbers}, **extra)
        declaration_checks(decl, dp)
        out.append(decl)
    return out


def referenced_names(problem: PhaseProblem) -> set[str]:
    """Every name some expression of the problem uses (to warn about unused declarations)."""
    trees = [e for _, e in problem.expressions] + list(problem.dynamics)
    trees += [c.expr for c in problem.path + problem.boundary]
    trees += [e for e in (problem.objective.expr, problem.objective.integrand) if e is not None]
    out: set[str] = set()
    for e in trees:
        out |= names_used(e)
    return out
