"""Several phases of an ``ocp`` problem (``../shared/specs/ocp.md``, "Several phases"): params -> typed problem.

``params.phases`` is a list of phases, each a single-phase block (``name``, ``states``,
``controls``, ``time``, ``expressions``, ``dynamics``, ``path``, ``boundary``, ``transcription``,
``guess``); ``constants``, ``tables``, ``parameters``, ``objective``, ``links``, ``guess.from_job``
and ``plots`` stay at the top level.  Each phase is parsed by the single-phase parser
(:func:`solvers.ocp.spec.parse_problem`) with the top-level constants, tables and parameters, so a
phase is an :class:`OcpProblem` whose objective is that phase's share of the integrand; its
errors are re-located under ``params.phases.<i>``.  The top-level events (the objective's
``expr`` and ``links``) are parsed with the multi-phase event functions ``initial(x, "phase")``,
``final(x, "phase")``, ``t0("phase")``, ``tf("phase")``.

Rules (each a 422 naming the field):

* phase names are unique; a phase's name is an identifier (hyphens allowed);
* ``objective.integrand`` is one expression (integrated over every phase) or an object phase name
  -> expression (those phases only);
* **linkage**: consecutive phases are continuous in time (``t0(next) = tf(previous)``) and in
  every state both declare; a link that relates ``final(x, "a")`` and ``initial(x, "b")`` of
  consecutive phases ``a``, ``b`` replaces the continuity of ``x`` between them, one that relates
  ``tf("a")`` and ``t0("b")`` replaces the time continuity (then ``t0(b) >= tf(a)`` still holds);
* a link may name phases that are not consecutive only with ``"non_consecutive": true``;
* **order in time**: phases run in the order listed, each lasting a positive time, so
  ``t0(1) <= tf(1) <= t0(2) <= tf(2) <= ...``; a problem whose fixed times and time bounds
  (``initial``, ``initial_lower``, ``initial_upper``, ``final``, ``final_lower``,
  ``final_upper``) admit no such times is a 422 naming the phase's field that cannot be met.

Standard library only (the API validates with it).
"""
from __future__ import annotations

import re
from dataclasses import replace

from solvers.ocp.expressions import (
    Boundary,
    EventTime,
    OcpInputError,
    Scope,
    parse_expression,
    walk,
)
from solvers.ocp.fields import (
    OcpLimits,
    constraints_at,
    list_at,
    number_at,
    object_at,
    unknown_fields,
)
from solvers.ocp.problem import Link, NamedPhase, Objective, OcpProblem, PhaseTime, TimeSpec

PHASE_FIELDS = ("name", "states", "controls", "time", "expressions", "dynamics", "path", "boundary",
                "transcription", "guess")
TOP_FIELDS = ("title", "constants", "tables", "parameters", "objective", "links", "phases", "guess", "plots",
              "accuracy", "accuracy_required")
SINGLE_ONLY = ("states", "controls", "time", "expressions", "dynamics", "path", "boundary", "transcription")
TIME_FIELDS = ("initial", "initial_lower", "initial_upper", "initial_guess", "final", "final_lower",
               "final_upper", "final_guess")
_PHASE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*\Z")
MAX_PHASES = 20


def _relocate(exc: OcpInputError, i: int) -> OcpInputError:
    """An error of phase ``i``'s single-phase parse, named where the user wrote it."""
    path = exc.path
    for top in ("params.constants", "params.tables", "params.parameters", "params.objective", "params.title"):
        if path == top or path.startswith(top + "."):
            return exc
    return OcpInputError("params.phases." + str(i) + path[len("params"):], exc.reason)


def _time(raw: dict, path: str, first: bool) -> PhaseTime:
    unknown_fields(raw, TIME_FIELDS, path)
    vals = {k: number_at(raw.get(k), f"{path}.{k}") for k in TIME_FIELDS}
    if first and "initial" not in raw:
        vals["initial"] = 0.0          # as a single phase: t0 = 0 unless stated (null: free)
    for end in ("initial", "final"):
        lo, hi = vals[f"{end}_lower"], vals[f"{end}_upper"]
        if lo is not None and hi is not None and lo > hi:
            raise OcpInputError(f"{path}.{end}_lower", f"lower {lo:g} > upper {hi:g}")
        v = vals[end]
        if v is not None and ((lo is not None and v < lo) or (hi is not None and v > hi)):
            raise OcpInputError(f"{path}.{end}", f"{v:g} is outside [{lo}, {hi}]")
    return PhaseTime(**vals)


def check_order(times: list[PhaseTime]) -> None:
    """The phases' windows admit ``t0(1) <= tf(1) <= t0(2) <= ...`` (module docstring), else a 422."""
    inf = float("inf")

    def lo(*v):
        return max((x for x in v if x is not None), default=-inf)

    def hi(*v):
        return min((x for x in v if x is not None), default=inf)

    # the chain s0 <= e0 <= s1 <= e1 ...: earliest times forward, latest backward
    early, late, where = [], [], []
    for i, t in enumerate(times):
        p = f"params.phases.{i}.time"
        early += [lo(t.initial, t.initial_lower), lo(t.final, t.final_lower)]
        late += [hi(t.initial, t.initial_upper), hi(t.final, t.final_upper)]
        where += [(p, "initial"), (p, "final")]
    for j in range(1, len(early)):
        early[j] = max(early[j], early[j - 1])
    for j in range(len(late) - 2, -1, -1):
        late[j] = min(late[j], late[j + 1])
    for j, (e, la) in enumerate(zip(early, late)):
        if e > la:
            p, end = where[j]
            raise OcpInputError(f"{p}.{end}", f"the phases cannot be ordered in time: the {end} time of this phase "
                                f"would have to be at least {e:g} (its own or an earlier phase's bounds) and at "
                                f"most {la:g} (its own or a later phase's bounds); phases run in the order listed, "
                                "each ending no earlier than it starts and no later than the next one starts")
    for i, t in enumerate(times):
        if t.initial is not None and t.final is not None and not t.final > t.initial:
            raise OcpInputError(f"params.phases.{i}.time.final",
                                f"final time {t.final:g} must be after initial {t.initial:g}")


def _guess_times(times: list[PhaseTime], raw_guess_tf: list[float | None]) -> list[tuple[float, float]]:
    out, prev = [], None
    for t, gtf in zip(times, raw_guess_tf):
        t0 = next((v for v in (t.initial, t.initial_guess) if v is not None), None)
        if t0 is None:
            t0 = prev if prev is not None else (_mid(t.initial_lower, t.initial_upper) or 0.0)
        tf = next((v for v in (t.final, gtf, t.final_guess) if v is not None), None)
        if tf is None:
            m = _mid(t.final_lower, t.final_upper)
            tf = m if m is not None and m > t0 else t0 + 1.0
        if not tf > t0:
            tf = t0 + 1.0
        out.append((t0, tf))
        prev = tf
    return out


def _mid(lo, hi):
    if lo is not None and hi is not None:
        return 0.5 * (lo + hi)
    return lo if lo is not None else hi


def parse_phases(params: dict, limits: OcpLimits, parse_problem) -> OcpProblem:
    """Validate a multi-phase ``params`` object (module docstring); :class:`OcpInputError` otherwise.
    ``parse_problem``: the single-phase parser (:func:`solvers.ocp.spec.parse_problem`, which calls
    this one: passed in, so neither module imports the other)."""
    P = "params"
    for k in SINGLE_ONLY:
        if params.get(k) not in (None, [], {}):
            raise OcpInputError(f"{P}.{k}", f"'{k}' belongs to a phase when params.phases is given: "
                                            f"write it in each phase (params.phases.<i>.{k})")
    unknown_fields({k: v for k, v in params.items() if k not in SINGLE_ONLY}, TOP_FIELDS, P)
    accuracy = number_at(params.get("accuracy"), f"{P}.accuracy")
    if accuracy is not None and not accuracy > 0:
        raise OcpInputError(f"{P}.accuracy", "must be positive")
    accuracy_required = params.get("accuracy_required", True)
    if not isinstance(accuracy_required, bool):
        raise OcpInputError(f"{P}.accuracy_required", "true or false")
    raw_phases = list_at(params.get("phases"), f"{P}.phases")
    if not raw_phases:
        raise OcpInputError(f"{P}.phases", "at least one phase is required")
    if len(raw_phases) > MAX_PHASES:
        raise OcpInputError(f"{P}.phases", f"{len(raw_phases)} phases exceed the limit max_phases={MAX_PHASES}")
    obj_raw = object_at(params.get("objective"), f"{P}.objective")
    unknown_fields(obj_raw, ("sense", "expr", "integrand"), f"{P}.objective")
    sense = obj_raw.get("sense", "minimize")
    if sense not in ("minimize", "maximize"):
        raise OcpInputError(f"{P}.objective.sense", f"'{sense}' is neither 'minimize' nor 'maximize'")
    if obj_raw.get("expr") is None and obj_raw.get("integrand") is None:
        raise OcpInputError(f"{P}.objective", "give expr (a Mayer term), integrand (a Lagrange term) or both")
    guess_raw = object_at(params.get("guess"), f"{P}.guess")
    unknown_fields(guess_raw, ("from_job",), f"{P}.guess")
    from_job = guess_raw.get("from_job")
    if from_job is not None and not isinstance(from_job, str):
        raise OcpInputError(f"{P}.guess.from_job", "a job id string")

    names: list[str] = []
    for i, ph in enumerate(raw_phases):
        ph = object_at(ph, f"{P}.phases.{i}")
        unknown_fields(ph, PHASE_FIELDS, f"{P}.phases.{i}")
        nm = ph.get("name")
        if not isinstance(nm, str) or not _PHASE_NAME.match(nm) or len(nm) > 64:
            raise OcpInputError(f"{P}.phases.{i}.name", "a phase name is required: letters, digits, _ and -, "
                                                        "not starting with a digit, at most 64 characters")
        if nm in names:
            raise OcpInputError(f"{P}.phases.{i}.name", f"duplicated phase name '{nm}' (also phase {names.index(nm)})")
        names.append(nm)
    integrand = obj_raw.get("integrand")
    if isinstance(integrand, dict):
        for k in integrand:
            if k not in names:
                from solvers.ocp.expressions import closest
                raise OcpInputError(f"{P}.objective.integrand.{k}", f"unknown phase '{k}'; did you mean "
                                                                      f"'{closest(str(k), names)}'?")

    times = [_time(object_at(object_at(ph, "").get("time"), f"{P}.phases.{i}.time"), f"{P}.phases.{i}.time", i == 0)
             for i, ph in enumerate(raw_phases)]
    check_order(times)
    gtf = []
    for i, ph in enumerate(raw_phases):
        g = object_at(ph.get("guess"), f"{P}.phases.{i}.guess")
        if g.get("from_job") is not None:
            raise OcpInputError(f"{P}.phases.{i}.guess.from_job", "a warm start is for the whole problem: "
                                                                   "give params.guess.from_job")
        gtf.append(number_at(g.get("tf"), f"{P}.phases.{i}.guess.tf"))
    guesses = _guess_times(times, gtf)

    phases = []
    top = {k: params[k] for k in ("title", "constants", "tables", "parameters") if k in params}
    for i, (ph, t, (t0g, tfg)) in enumerate(zip(raw_phases, times, guesses)):
        body = {**top, **{k: v for k, v in ph.items() if k not in ("name", "time")}}
        body["time"] = {"initial": t0g}
        mine = integrand.get(names[i]) if isinstance(integrand, dict) else integrand
        body["objective"] = {"sense": sense, **({"integrand": mine} if mine is not None else {"expr": 0})}
        try:
            prob = parse_problem(body, limits)
        except OcpInputError as exc:
            if exc.path.startswith("params.objective.integrand"):
                where = f".{names[i]}" if isinstance(integrand, dict) else ""
                exc = OcpInputError(f"params.objective.integrand{where}", f"in phase '{names[i]}': {exc.reason}")
            raise _relocate(exc, i) from None
        obj = replace(prob.objective, expr=None, expr_text="")
        ts = TimeSpec(initial=t0g, final=t.final, final_lower=t.final_lower, final_upper=t.final_upper,
                      final_guess=tfg)
        prob = replace(prob, objective=obj, phase=replace(prob.phase, time=ts))
        phases.append(NamedPhase(name=names[i], time=t, problem=prob))

    first = phases[0].problem
    top_names = {n: "constant" for n, _ in first.constants}
    top_names.update({q.name: "parameter" for q in first.parameters})
    declared = {p.name: {**{s.name: "state" for s in p.problem.states},
                         **{c.name: "control" for c in p.problem.controls}} for p in phases}
    tables = {tb.name: len(tb.axes) for tb in first.tables}

    def parse(text, path, scope):
        return parse_expression(text, path=path, scope=scope, max_chars=limits.max_expression_chars,
                                max_nodes=limits.max_expression_nodes)

    ev_obj = Scope(top_names, tables, boundary=True, where="the objective's expr", phases=declared)
    expr = None if obj_raw.get("expr") is None else parse(obj_raw["expr"], f"{P}.objective.expr", ev_obj)
    objective = Objective(sense=sense, expr=expr, integrand=None, expr_text=str(obj_raw.get("expr") or ""),
                          integrand_text=str(integrand or ""))

    links_raw = list_at(params.get("links"), f"{P}.links")
    flags = []
    for i, lk in enumerate(links_raw):
        lk = object_at(lk, f"{P}.links.{i}")
        nc = lk.get("non_consecutive", False)
        if not isinstance(nc, bool):
            raise OcpInputError(f"{P}.links.{i}.non_consecutive", "true or false")
        flags.append(nc)
    plain = [{k: v for k, v in object_at(lk, "").items() if k != "non_consecutive"} for lk in links_raw]
    parsed = constraints_at(plain, f"{P}.links", Scope(top_names, tables, boundary=True, where="links",
                                                       phases=declared), parse, limits)
    links = []
    for i, (c, nc) in enumerate(zip(parsed, flags)):
        used = {n.phase for n in walk(c.expr) if isinstance(n, (Boundary, EventTime)) and n.phase}
        idx = sorted(names.index(u) for u in used)
        if idx and idx[-1] - idx[0] > 1 and not nc:
            raise OcpInputError(f"{P}.links.{i}.expr", f"links phases '{names[idx[0]]}' and '{names[idx[-1]]}', "
                                                       "which are not consecutive; set \"non_consecutive\": true "
                                                       "on this link if that is meant")
        links.append(Link(expr=c.expr, text=c.text, lower=c.lower, upper=c.upper, name=c.name or f"link_{i}",
                          phases=tuple(names[j] for j in idx), non_consecutive=nc))

    time_links, state_links = [], []
    for k in range(len(phases) - 1):
        a, b = names[k], names[k + 1]
        events = [_events(lk.expr) for lk in links]
        if not any(("tf", a) in ev and ("t0", b) in ev for ev in events):
            time_links.append(k)
        shared = [s for s in phases[k].problem.state_names if s in phases[k + 1].problem.state_names]
        for x in shared:
            if not any(("final", x, a) in ev and ("initial", x, b) in ev for ev in events):
                state_links.append((k, x))

    plots = []
    reportable = {"t"}.union(*[set(p.problem.state_names) | set(p.problem.control_names)
                               | {n for n, _ in p.problem.expressions} for p in phases])
    for i, pair in enumerate(list_at(params.get("plots"), f"{P}.plots")):
        pair = list_at(pair, f"{P}.plots.{i}")
        if len(pair) != 2:
            raise OcpInputError(f"{P}.plots.{i}", "a plot is a pair of names [x, y]")
        for j, nm in enumerate(pair):
            if nm not in reportable:
                raise OcpInputError(f"{P}.plots.{i}.{j}", f"'{nm}' is not a state, control, expression of a phase or t")
        plots.append((pair[0], pair[1]))
    return OcpProblem(title=first.title, constants=first.constants, tables=first.tables,
                             parameters=first.parameters, phases=tuple(phases), objective=objective,
                             links=tuple(links), time_links=tuple(time_links), state_links=tuple(state_links),
                             from_job=from_job, plots=tuple(plots), accuracy=accuracy,
                             accuracy_required=accuracy_required)


def _events(expr) -> set[tuple]:
    out = set()
    for n in walk(expr):
        if isinstance(n, Boundary) and n.phase:
            out.add((n.which, n.name, n.phase))
        elif isinstance(n, EventTime):
            out.add((n.which, n.phase))
    return out


__all__ = ["check_order", "parse_phases"]
