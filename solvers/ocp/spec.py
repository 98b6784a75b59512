"""The ``ocp`` problem as data: the spec's ``params`` object -> validated, typed, frozen :class:`OcpProblem`.

One parser for one phase and several: what the phases share (title, tables, constants, parameters,
objective, accuracy) is read here once; a problem posed with the single-phase fields is the
one-phase case, its params read as that phase at ``params`` (:func:`solvers.ocp.phase_spec.parse_phase`),
and ``params.phases`` are read each at ``params.phases.<i>`` by the same function, with what only
several phases have (names, windows in time, links, the events objective) from
:mod:`solvers.ocp.phases_spec`.

:func:`parse_problem` checks everything ``../shared/specs/ocp.md`` lists under "Errors" and raises
:class:`OcpInputError` (``path``: the field, as ``params.dynamics.v``; ``reason``: why) at the
first problem found; what it returns can be built.  Expressions become trees of
:mod:`solvers.ocp.expressions`.  Standard library only: the API process validates with it before
it stores a job, and loads no numpy or CasADi for that.
"""
from __future__ import annotations

import math
from dataclasses import replace

from solvers.ocp import phases_spec
from solvers.ocp.expressions import OcpInputError, Scope
from solvers.ocp.phase_spec import Shared, declarations, parse_phase, time_spec
from solvers.ocp.problem import NamedPhase, Objective, OcpProblem, PhaseProblem, PhaseTime, TableDecl, TimeSpec
from solvers.ocp.robust.links import carried_links
from solvers.ocp.robust.spec import parse_robust
from solvers.ocp.shape import FIELDS
from solvers.ocp.readers import (
    Names,
    OcpLimits,
    expression_parser,
    list_at,
    number_at,
    object_at,
    unknown_fields,
)

__all__ = ["OcpInputError", "OcpLimits", "OcpProblem", "parse_problem"]

TOP_FIELDS = FIELDS["params"]
DEFAULT_LIMITS = OcpLimits()


def parse_problem(params: dict, limits: OcpLimits = DEFAULT_LIMITS) -> OcpProblem:
    """Validate the spec's ``params`` object and return the problem; :class:`OcpInputError` otherwise."""
    P = "params"
    if not isinstance(params, dict):
        raise OcpInputError(P, "expected an object")
    several = params.get("phases") is not None
    if several:
        for k in phases_spec.SINGLE_ONLY:
            if params.get(k) not in (None, [], {}):
                raise OcpInputError(f"{P}.{k}", f"'{k}' belongs to a phase when params.phases is given: "
                                                f"write it in each phase (params.phases.<i>.{k})")
        unknown_fields({k: v for k, v in params.items() if k not in phases_spec.SINGLE_ONLY},
                       phases_spec.TOP_FIELDS, P)
    else:
        unknown_fields(params, TOP_FIELDS, P)
    shared = _shared(params, limits)
    objective = object_at(params.get("objective"), f"{P}.objective")
    if not objective:
        raise OcpInputError(f"{P}.objective", "an objective is required: {\"sense\", \"expr\"?, \"integrand\"?}")
    unknown_fields(objective, FIELDS["objective"], f"{P}.objective")
    sense = objective.get("sense", "minimize")
    if sense not in ("minimize", "maximize"):
        raise OcpInputError(f"{P}.objective.sense", f"'{sense}' is neither 'minimize' nor 'maximize'")
    if objective.get("expr") is None and objective.get("integrand") is None:
        raise OcpInputError(f"{P}.objective", "give expr (Mayer term), integrand (Lagrange term) or both")
    if shared.starts > 1 and (params.get("uncertainty") is not None or params.get("robust") is not None):
        # each start would be a robust solve and its Monte Carlo: search first, then design from the best
        raise OcpInputError(f"{P}.search.starts", "several starts of a robust design are not done: search the "
                                                  "deterministic problem (search.starts), then warm-start the "
                                                  "robust design from its best answer (initial_guess.from_job)")
    if several:
        problem = _several(params, shared, objective, limits)
        return replace(problem, robust=_robust(params, problem, limits))
    time = time_spec(object_at(params.get("time"), f"{P}.time"), f"{P}.time")
    one = parse_phase(params, path=P, shared=shared, time=time, objective=objective, limits=limits, mayer=True)
    window = PhaseTime(initial=time.initial, final=time.final, final_lower=time.final_lower,
                       final_upper=time.final_upper, final_guess=time.final_guess)
    problem = OcpProblem(title=shared.title, constants=shared.constants, tables=shared.tables,
                      parameters=shared.parameters, phases=(NamedPhase("", window, one),), objective=one.objective,
                      from_job=one.phase.guess.from_job, plots=_plots(params, [one]), accuracy=shared.accuracy,
                      accuracy_required=shared.accuracy_required, single=True, starts=shared.starts,
                      seed=shared.seed)
    return replace(problem, robust=_robust(params, problem, limits))


def _robust(params: dict, problem: OcpProblem, limits: OcpLimits):
    """``uncertainty`` and ``robust`` (:mod:`solvers.ocp.robust.spec`) of the problem, one phase or several:
    the initial sigmas name the first phase's states, the robust constraints any phase's path or boundary
    constraints (a name in several phases is held in each)."""
    if params.get("uncertainty") is None and params.get("robust") is None:
        return None
    carried_links(problem)       # a link of states that cannot carry the covariance is refused, named
    trees, path, boundary = [], [], []
    for named in problem.phases:
        ph, obj = named.problem.phase, named.problem.objective
        trees += [*ph.dynamics, *(e for _, e in ph.expressions), *(c.expr for c in ph.path),
                  *(c.expr for c in ph.boundary), *(e for e in (obj.expr, obj.integrand) if e is not None)]
        path += [c.name for c in ph.path]
        boundary += [c.name for c in ph.boundary]
    trees += [lk.expr for lk in problem.links] + ([problem.objective.expr] if problem.objective.expr else [])
    return parse_robust(params, constants=dict(problem.constants), states=problem.phases[0].problem.phase.state_names,
                        trees=trees, path_names=tuple(dict.fromkeys(path)), boundary_names=tuple(dict.fromkeys(boundary)),
                        sense=problem.objective.sense, max_samples=limits.max_monte_carlo_samples)


def _shared(params: dict, limits: OcpLimits) -> Shared:
    """What every phase shares: title, tables, constants, parameters, accuracy."""
    P = "params"
    title = params.get("title") or ""
    if not isinstance(title, str) or len(title) > 500:
        raise OcpInputError(f"{P}.title", "a string of at most 500 characters")

    # tables first: their names are callable in every expression
    tables_raw = object_at(params.get("tables"), f"{P}.tables")
    if len(tables_raw) > limits.max_tables:
        raise OcpInputError(f"{P}.tables", f"{len(tables_raw)} tables exceed the limit max_tables={limits.max_tables}")
    table_dims: dict[str, int] = {}
    names = Names(table_dims)
    tables = []
    total_values = 0
    for tname, tdef in tables_raw.items():
        tp = f"{P}.tables.{tname}"
        names.declare(tname, "table", tp)
        tdef = object_at(tdef, tp)
        unknown_fields(tdef, FIELDS["table"], tp)
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

    # declared in each phase after its states and controls (a clash is reported at the parameter)
    parameters = declarations(params, P, "parameters", names.copy(), limits)
    accuracy = number_at(params.get("accuracy"), f"{P}.accuracy")
    if accuracy is not None and not accuracy > 0:
        raise OcpInputError(f"{P}.accuracy", "must be positive")
    accuracy_required = params.get("accuracy_required", True)
    if not isinstance(accuracy_required, bool):
        raise OcpInputError(f"{P}.accuracy_required", "expected true or false")
    starts, seed = _search(params, limits)
    return Shared(title=title, tables=tuple(tables), constants=tuple(constants), parameters=tuple(parameters),
                  names=names, accuracy=accuracy, accuracy_required=accuracy_required, starts=starts, seed=seed)


def _search(params: dict, limits: OcpLimits) -> tuple[int, int]:
    """``search: {"starts", "seed"}``: how many initial guesses (solvers.ocp.starts), within the limit."""
    P = "params.search"
    search = object_at(params.get("search"), P)
    unknown_fields(search, FIELDS["search"], P)
    out = []
    for key, default, lo, hi in (("starts", 1, 1, limits.max_starts), ("seed", 0, 0, 2**31 - 1)):
        v = search.get(key, default)
        if v is None:
            v = default
        if isinstance(v, bool) or not isinstance(v, int):
            raise OcpInputError(f"{P}.{key}", "expected an integer")
        if v < lo:
            raise OcpInputError(f"{P}.{key}", f"at least {lo}")
        if v > hi:
            raise OcpInputError(f"{P}.{key}", f"{v} starts exceed the limit max_starts={hi}" if key == "starts"
                                else f"at most {hi}")
        out.append(v)
    return out[0], out[1]


def _several(params: dict, shared: Shared, objective: dict, limits: OcpLimits) -> OcpProblem:
    """``params.phases``: each phase by :func:`parse_phase`, then the events objective and the links."""
    P = "params"
    raw_phases = list_at(params.get("phases"), f"{P}.phases")
    if not raw_phases:
        raise OcpInputError(f"{P}.phases", "at least one phase is required")
    if len(raw_phases) > phases_spec.MAX_PHASES:
        raise OcpInputError(f"{P}.phases", f"{len(raw_phases)} phases exceed the limit "
                                           f"max_phases={phases_spec.MAX_PHASES}")
    guess_raw = object_at(params.get("guess"), f"{P}.guess")
    unknown_fields(guess_raw, FIELDS["params.phases.guess"], f"{P}.guess")
    from_job = guess_raw.get("from_job")
    if from_job is not None and not isinstance(from_job, str):
        raise OcpInputError(f"{P}.guess.from_job", "a job id string")
    names = phases_spec.phase_names(raw_phases)
    integrand = objective.get("integrand")
    phases_spec.check_integrands(integrand, names)
    times, guesses = phases_spec.windows(raw_phases)
    sense = objective.get("sense", "minimize")
    phases = []
    for i, (ph, t, (t0g, tfg)) in enumerate(zip(raw_phases, times, guesses)):
        mine = integrand.get(names[i]) if isinstance(integrand, dict) else integrand
        ts = TimeSpec(initial=t0g, final=t.final, final_lower=t.final_lower, final_upper=t.final_upper,
                      final_guess=tfg)
        try:
            prob = parse_phase(ph, path=f"{P}.phases.{i}", shared=shared, time=ts,
                               objective={"sense": sense, "integrand": mine}, limits=limits, mayer=False)
        except OcpInputError as exc:
            if not exc.path.startswith("params.objective.integrand"):
                raise
            where = f".{names[i]}" if isinstance(integrand, dict) else ""
            raise OcpInputError(f"params.objective.integrand{where}", f"in phase '{names[i]}': {exc.reason}") from None
        phases.append(NamedPhase(name=names[i], time=t, problem=prob))

    top_names = {n: "constant" for n, _ in shared.constants}
    top_names.update({q.name: "parameter" for q in shared.parameters})
    declared = {p.name: {**{s.name: "state" for s in p.problem.states},
                         **{c.name: "control" for c in p.problem.controls}} for p in phases}
    tables = {tb.name: len(tb.axes) for tb in shared.tables}
    parse = expression_parser(limits)
    ev_obj = Scope(top_names, tables, boundary=True, where="the objective's expr", phases=declared)
    expr = None if objective.get("expr") is None else parse(objective["expr"], f"{P}.objective.expr", ev_obj)
    links = phases_spec.parse_links(params, names, Scope(top_names, tables, boundary=True, where="links",
                                                         phases=declared), parse, limits)
    time_links, state_links = phases_spec.linkage(phases, links)
    return OcpProblem(title=shared.title, constants=shared.constants, tables=shared.tables,
                      parameters=shared.parameters, phases=tuple(phases),
                      objective=Objective(sense=sense, expr=expr, integrand=None,
                                          expr_text=str(objective.get("expr") or ""),
                                          integrand_text=str(integrand or "")),
                      links=links, time_links=time_links, state_links=state_links, from_job=from_job,
                      plots=_plots(params, [p.problem for p in phases]), accuracy=shared.accuracy,
                      accuracy_required=shared.accuracy_required, starts=shared.starts, seed=shared.seed)


def _plots(params: dict, phases: list[PhaseProblem]) -> tuple[tuple[str, str], ...]:
    """The extra plot pairs: each name a state, control or expression of some phase, or t."""
    reportable = {"t"}.union(*[set(p.state_names) | set(p.control_names) | {n for n, _ in p.expressions}
                               for p in phases])
    plots = []
    for i, pair in enumerate(list_at(params.get("plots"), "params.plots")):
        pp = f"params.plots.{i}"
        pair = list_at(pair, pp)
        if len(pair) != 2:
            raise OcpInputError(pp, "a plot is a pair of names [x, y]")
        for j, nm in enumerate(pair):
            if nm not in reportable:
                raise OcpInputError(f"{pp}.{j}", f"'{nm}' is not a state, control, expression or t")
        plots.append((pair[0], pair[1]))
    return tuple(plots)
