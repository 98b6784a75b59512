"""Plots of an ``ocp`` result: every state, control and expression against time, and each pair ``[x, y]``
the problem asked for in ``plots``; one phase or several, drawn by the same code.

A result posed as one phase is the one-phase case (its top-level ``trajectory``); several phases are
drawn one after the other on the same axes (a phase that lacks a quantity leaves a gap), each in its
own colour and labelled with its name, the boundaries between phases marked by vertical lines.  The
plot list follows from the stored result alone (its trajectories' names and its ``plots`` pairs), so
``GET /v1/jobs/{id}/plots`` needs nothing else; rendering, caching, the report and the formats are the
shared machinery's (:mod:`app.results.plots`).  Bounds come from the job's parameters when drawn.
"""
from __future__ import annotations

from app.results.plots import PlotDef, floats

MAX_TIME_PLOTS = 300   # 50 states + 20 controls + 200 expressions fit; a bound on a report's size


def _phases(result: dict) -> list[dict]:
    """The result's phases, each with a trajectory; a single phase as the one ``{"name": ""}``."""
    if result.get("phases"):
        return [p for p in result["phases"] if isinstance(p, dict) and isinstance(p.get("trajectory"), dict)]
    tr = result.get("trajectory")
    if not isinstance(tr, dict) or "t" not in tr:
        return []
    return [{"name": "", "t0": result.get("t0"), "trajectory": tr, "verification": result.get("verification")}]


def label_of(name: str, result: dict) -> str:
    """``name (unit)`` with the unit the problem declared for it (``t (s)``)."""
    if name == "t":
        return f"t ({(result.get('units') or {}).get('t', 's')})"
    unit = (result.get("units") or {}).get(name)
    return f"{name} ({unit})" if unit else name


def _params_of(params: dict | None, phase: str) -> dict:
    """The parameters that declare ``phase``'s states, controls and path (the params themselves for one)."""
    for ph in (params or {}).get("phases") or []:
        if isinstance(ph, dict) and ph.get("name") == phase:
            return ph
    return params or {}


def declared_bounds(params: dict, name: str) -> tuple[float | None, float | None]:
    """The lower and upper bound ``params`` declare for a state, a control or a path expression."""
    for group in ("states", "controls"):
        for d in params.get(group) or []:
            if isinstance(d, dict) and d.get("name") == name:
                return d.get("lower"), d.get("upper")
    for c in params.get("path") or []:   # a path constraint written as just this expression's name
        if isinstance(c, dict) and str(c.get("expr", "")).strip() == name:
            return c.get("lower"), c.get("upper")
    return None, None


def _dense(phase: dict) -> dict | None:
    dense = (phase.get("verification") or {}).get("trajectory")   # the re-flight's points, when kept
    return dense if isinstance(dense, dict) and dense.get("t") else None


def _draw(fig, r, params, x: str, y: str, *, bounds: bool):
    ax = fig.add_subplot()
    phases = _phases(r)
    several = len(phases) > 1 or bool(phases and phases[0]["name"])
    drawn_bounds = set()
    for i, p in enumerate(phases):
        tr = p["trajectory"]
        if not (isinstance(tr.get(x), list) and isinstance(tr.get(y), list)):
            continue
        label = p["name"] if several else "solution (nodes)"
        ax.plot(floats(tr[x]), floats(tr[y]), "o-", ms=2 if several else 3, lw=1, color=f"C{i % 10}", label=label)
        dense = _dense(p)
        if dense and dense.get(x) and dense.get(y):
            ax.plot(floats(dense[x]), floats(dense[y]), "-", lw=1, label="re-flown (verification)")
        if bounds:
            for b, what in zip(declared_bounds(_params_of(params, p["name"]), y), ("lower bound", "upper bound")):
                if b is not None and (b, what) not in drawn_bounds:
                    drawn_bounds.add((b, what))
                    ax.axhline(b, color="C3", ls="--", lw=1, label=what)
    if several and x == "t":
        top = ax.get_ylim()[1]
        for p in phases[1:]:
            if p.get("t0") is not None:
                ax.axvline(p["t0"], color="0.4", ls=":", lw=1)
                ax.text(p["t0"], top, f" {p['name']}", rotation=90, va="top", ha="left", fontsize=8, color="0.3")
    ax.set_xlabel(label_of(x, r))
    ax.set_ylabel(label_of(y, r))
    ax.legend(title="phase" if several else None)


def _against_time(name: str):
    def draw(fig, r, params):
        _draw(fig, r, params, "t", name, bounds=True)
    return draw


def _pair(x: str, y: str):
    def draw(fig, r, params):
        _draw(fig, r, params, x, y, bounds=False)
    return draw


def _has(*names: str):
    return lambda r: any(all(isinstance(p["trajectory"].get(n), list) for n in names) for p in _phases(r))


def plots(result: dict) -> list[PlotDef]:
    """One plot per quantity against time (the phases on one axis), then the pairs of ``result["plots"]``."""
    phases = _phases(result)
    suffix = " (all phases)" if result.get("phases") else ""
    names: list[str] = []
    for p in phases:
        names += [n for n in p["trajectory"] if n != "t" and n not in names]
    out = [PlotDef(f"t-{n}", f"{n} against time{suffix}", _against_time(n), _has("t", n))
           for n in names][:MAX_TIME_PLOTS]
    seen = {p.name for p in out}
    for pair in result.get("plots") or []:
        if isinstance(pair, list) and len(pair) == 2:
            x, y = (str(v) for v in pair)
            if f"{x}-{y}" not in seen:
                seen.add(f"{x}-{y}")
                out.append(PlotDef(f"{x}-{y}", f"{y} against {x}{suffix}", _pair(x, y), _has(x, y)))
    return out
