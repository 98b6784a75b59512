"""What only several phases of an ``ocp`` problem have (``../shared/specs/ocp.md``, "Several phases").

``params.phases`` is a list of phases, each a single-phase block (``name``, ``states``,
``controls``, ``time``, ``expressions``, ``dynamics``, ``path``, ``boundary``, ``transcription``,
``guess``); ``constants``, ``tables``, ``parameters``, ``objective``, ``links``, ``guess.from_job``
and ``plots`` stay at the top level.  Each phase is read by the one phase parser
(:func:`solvers.ocp.phase_spec.parse_phase`, called by :func:`solvers.ocp.spec.parse_problem`);
here: the phases' names, their windows in time, the guesses of their ends, and the links, parsed
with the multi-phase event functions ``initial(x, "phase")``, ``final(x, "phase")``,
``t0("phase")``, ``tf("phase")``.

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

from solvers.ocp.expressions import Boundary, EventTime, OcpInputError, closest, walk
from solvers.ocp.problem import Link, NamedPhase, PhaseTime
from solvers.ocp.shape import FIELDS
from solvers.ocp.readers import OcpLimits, constraints_at, list_at, number_at, object_at, unknown_fields

PHASE_FIELDS = FIELDS["phase"]
TOP_FIELDS = FIELDS["params.phases"]
SINGLE_ONLY = ("states", "controls", "time", "expressions", "dynamics", "path", "boundary", "transcription")
TIME_FIELDS = FIELDS["phase.time"]
_PHASE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*\Z")
MAX_PHASES = 20


def phase_names(raw_phases: list) -> list[str]:
    """The phases' names: unique, identifiers (hyphens allowed); each phase's fields known."""
    names: list[str] = []
    for i, ph in enumerate(raw_phases):
        ph = object_at(ph, f"params.phases.{i}")
        unknown_fields(ph, PHASE_FIELDS, f"params.phases.{i}")
        nm = ph.get("name")
        if not isinstance(nm, str) or not _PHASE_NAME.match(nm) or len(nm) > 64:
            raise OcpInputError(f"params.phases.{i}.name", "a phase name is required: letters, digits, _ and -, "
                                                           "not starting with a digit, at most 64 characters")
        if nm.startswith("_"):   # as for every other name (solvers.ocp.readers.Names): Python's own live there
            raise OcpInputError(f"params.phases.{i}.name", f"'{nm}' is reserved: a name cannot begin with an "
                                                           "underscore")
        if nm in names:
            raise OcpInputError(f"params.phases.{i}.name", f"duplicated phase name '{nm}' (also phase "
                                                           f"{names.index(nm)})")
        names.append(nm)
    return names


def check_integrands(integrand, names: list[str]) -> None:
    """``objective.integrand`` as an object names phases that exist."""
    if isinstance(integrand, dict):
        for k in integrand:
            if k not in names:
                raise OcpInputError(f"params.objective.integrand.{k}", f"unknown phase '{k}'; did you mean "
                                                                      f"'{closest(str(k), names)}'?")


def windows(raw_phases: list) -> tuple[list[PhaseTime], list[tuple[float, float]]]:
    """Each phase's time window (ordered in time, else a 422) and the guesses of its t0 and tf."""
    P = "params"
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
    return times, _guess_times(times, gtf)


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


def parse_links(params: dict, names: list[str], scope, parse, limits: OcpLimits) -> tuple[Link, ...]:
    """``params.links``: event constraints between phases, consecutive unless marked ``non_consecutive``."""
    P = "params"
    links_raw = list_at(params.get("links"), f"{P}.links")
    flags = []
    for i, lk in enumerate(links_raw):
        lk = object_at(lk, f"{P}.links.{i}")
        nc = lk.get("non_consecutive", False)
        if not isinstance(nc, bool):
            raise OcpInputError(f"{P}.links.{i}.non_consecutive", "true or false")
        flags.append(nc)
    plain = [{k: v for k, v in object_at(lk, "").items() if k != "non_consecutive"} for lk in links_raw]
    parsed = constraints_at(plain, f"{P}.links", scope, parse, limits)
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
    return tuple(links)


def linkage(phases: list[NamedPhase], links) -> tuple[tuple[int, ...], tuple[tuple[int, str], ...]]:
    """The default continuities no link replaces: ``(time_links, state_links)`` (module docstring)."""
    time_links, state_links = [], []
    events = [_events(lk.expr) for lk in links]
    for k in range(len(phases) - 1):
        a, b = phases[k].name, phases[k + 1].name
        if not any(("tf", a) in ev and ("t0", b) in ev for ev in events):
            time_links.append(k)
        shared = [s for s in phases[k].problem.state_names if s in phases[k + 1].problem.state_names]
        for x in shared:
            if not any(("final", x, a) in ev and ("initial", x, b) in ev for ev in events):
                state_links.append((k, x))
    return tuple(time_links), tuple(state_links)


def _events(expr) -> set[tuple]:
    out: set[tuple] = set()
    for n in walk(expr):
        if isinstance(n, Boundary) and n.phase:
            out.add((n.which, n.name, n.phase))
        elif isinstance(n, EventTime):
            out.add((n.which, n.phase))
    return out
