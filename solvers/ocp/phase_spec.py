"""One phase of the ``ocp`` params -> :class:`PhaseProblem`: the same parser for a problem posed as one phase
(the params themselves, at ``params``) and for each of several (``params.phases.<i>``).

A phase declares its states and controls in a namespace that starts with the problem's tables and
constants (the parameters are declared after them, so a clash is reported at the parameter, as
the problem's declaration comes second), then its named expressions (each sees what is declared
and the expressions before it), its dynamics (one per state), path and boundary constraints, its
share of the objective (the integrand; the Mayer term too when the phase is the whole problem), its
transcription and its guess.  Errors name the field where the user wrote it.  Standard library only.
"""
from __future__ import annotations

from dataclasses import dataclass

from solvers.ocp.expressions import OcpInputError, Scope, closest, names_used
from solvers.ocp.problem import (
    ControlDecl,
    Guess,
    Objective,
    ParameterDecl,
    Phase,
    PhaseProblem,
    StateDecl,
    TimeSpec,
    Transcription,
)
from solvers.ocp.shape import CONTROL_NUMBERS, FIELDS, PARAMETER_NUMBERS, STATE_NUMBERS
from solvers.ocp.readers import (
    Names,
    OcpLimits,
    constraints_at,
    expression_parser,
    list_at,
    number_at,
    object_at,
    ordered_bounds,
    unit_at,
    unknown_fields,
)

METHODS = ("multiple_shooting", "lgl")


@dataclass(frozen=True)
class Shared:
    """What every phase of a problem shares: its title, tables, constants and parameters, parsed once,
    and the namespace they fill."""

    title: str
    tables: tuple
    constants: tuple
    parameters: tuple
    names: Names
    accuracy: float | None
    accuracy_required: bool
    starts: int = 1
    seed: int = 0


def parse_phase(raw: dict, *, path: str, shared: Shared, time: TimeSpec, objective: dict, limits: OcpLimits,
                mayer: bool) -> PhaseProblem:
    """Phase ``raw`` (at ``path``) with its ``time`` and its share of the ``objective`` (``{"sense",
    "integrand"?, "expr"?}``, checked for its form by the caller; ``mayer``: the phase is the whole
    problem, its objective's ``expr`` is parsed in the phase's events)."""
    names = shared.names.copy()
    tables = names.tables
    parse = expression_parser(limits)
    states = declarations(raw, path, "states", names, limits)
    if not states:
        raise OcpInputError(f"{path}.states", "at least one state is required")
    controls = declarations(raw, path, "controls", names, limits)
    for i, q in enumerate(shared.parameters):
        names.declare(q.name, "parameter", f"params.parameters.{i}.name")

    # named expressions: each sees what is declared plus the expressions before it
    exprs_raw = object_at(raw.get("expressions"), f"{path}.expressions")
    if len(exprs_raw) > limits.max_expressions:
        raise OcpInputError(f"{path}.expressions", f"{len(exprs_raw)} expressions exceed the limit "
                                                   f"max_expressions={limits.max_expressions}")
    base = {**names.kinds, "t": "time", "t0": "time", "tf": "time"}
    expressions: list = []
    for ename, etext in exprs_raw.items():
        ep = f"{path}.expressions.{ename}"
        names.declare(ename, "expression", ep)
        scope = Scope({**base, **{n: "expression" for n, _ in expressions}}, tables, where="expressions")
        expressions.append((ename, parse(etext, ep, scope)))
    along = Scope({**base, **{n: "expression" for n, _ in expressions}}, tables)

    dyn_raw = object_at(raw.get("dynamics"), f"{path}.dynamics")
    state_names = [s.name for s in states]
    for k in dyn_raw:
        if k not in state_names:
            hint = closest(str(k), state_names)
            raise OcpInputError(f"{path}.dynamics.{k}", f"dynamics for '{k}', which is not a declared state"
                                + (f"; did you mean '{hint}'?" if hint else ""))
    dynamics = []
    for i, s in enumerate(states):
        if s.name not in dyn_raw:
            raise OcpInputError(f"{path}.dynamics", f"state '{s.name}' has no dynamics ({path}.states.{i})")
        dynamics.append(parse(dyn_raw[s.name], f"{path}.dynamics.{s.name}", Scope(along.names, tables, where="dynamics")))

    path_scope = Scope(along.names, tables, where="a path constraint")
    event_names = {n: k for n, k in base.items() if k != "time" or n in ("t0", "tf")}
    event_scope = Scope(event_names, tables, boundary=True, where="a boundary constraint")
    path_c = constraints_at(raw.get("path"), f"{path}.path", path_scope, parse, limits)
    boundary = constraints_at(raw.get("boundary"), f"{path}.boundary", event_scope, parse, limits)

    op = "params.objective"
    expr = objective.get("expr") if mayer else None
    integrand = objective.get("integrand")
    share = Objective(
        sense=objective.get("sense", "minimize"),
        expr=None if expr is None else parse(
            expr, f"{op}.expr", Scope(event_names, tables, boundary=True, where="the objective's expr")),
        integrand=None if integrand is None else parse(
            integrand, f"{op}.integrand", Scope(along.names, tables, where="the objective's integrand")),
        expr_text=str(expr or ""), integrand_text=str(integrand or ""))

    transcription = transcription_at(object_at(raw.get("transcription"), f"{path}.transcription"),
                                     f"{path}.transcription", limits)
    guess = guess_at(object_at(raw.get("guess"), f"{path}.guess"), f"{path}.guess", states, controls)
    phase = Phase(states=tuple(states), controls=tuple(controls), time=time, expressions=tuple(expressions),
                  dynamics=tuple(dynamics), path=path_c, boundary=boundary, transcription=transcription, guess=guess)
    return PhaseProblem(title=shared.title, constants=shared.constants, tables=shared.tables,
                        parameters=shared.parameters, phase=phase, objective=share, accuracy=shared.accuracy,
                        accuracy_required=shared.accuracy_required)


# field -> (class, kind of name, its number fields, whether it has a unit, its limit)
DECLARATIONS = {
    "states": (StateDecl, "state", STATE_NUMBERS, True, "max_states"),
    "controls": (ControlDecl, "control", CONTROL_NUMBERS, True, "max_controls"),
    "parameters": (ParameterDecl, "parameter", PARAMETER_NUMBERS, False, "max_parameters"),
}


def declarations(raw: dict, where: str, field: str, names: Names, limits: OcpLimits) -> list:
    """The declared states, controls or parameters, in order, their names entered in ``names``."""
    cls, kind, numbers, has_unit, limit = DECLARATIONS[field]
    path = f"{where}.{field}"
    items = list_at(raw.get(field), path)
    cap = getattr(limits, limit)
    if len(items) > cap:
        raise OcpInputError(path, f"{len(items)} {field} exceed the limit {limit}={cap}")
    out = []
    for i, d in enumerate(items):
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
    """Every name some expression of the phase uses (to warn about unused declarations)."""
    trees = [e for _, e in problem.expressions] + list(problem.dynamics)
    trees += [c.expr for c in problem.path + problem.boundary]
    trees += [e for e in (problem.objective.expr, problem.objective.integrand) if e is not None]
    out: set[str] = set()
    for e in trees:
        out |= names_used(e)
    return out


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
    unknown_fields(t, FIELDS["time"], path)
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


def transcription_at(t: dict, path: str, limits: OcpLimits) -> Transcription:
    unknown_fields(t, FIELDS["transcription"], path)
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
    unknown_fields(g, FIELDS["guess"], path)

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
