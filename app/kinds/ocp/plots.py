"""Plots of an ``ocp`` result: every state, control and expression against time, and each pair
``[x, y]`` the problem asked for in ``plots``.

The plot list follows from the stored result alone (its trajectory's names and its ``plots``
pairs), so ``GET /v1/jobs/{id}/plots`` needs nothing else; rendering, caching, the report and the
formats are the shared machinery's (:mod:`app.results.plots`).  Bounds come from the job's
parameters when drawn.
"""
from __future__ import annotations

from app.results.plots import PlotDef, floats, pick

MAX_TIME_PLOTS = 300   # 50 states + 20 controls + 200 expressions fit; a bound on a report's size


def _label(name: str, result: dict) -> str:
    unit = (result.get("units") or {}).get(name)
    return f"{name} ({unit})" if unit else name


def _bounds(params: dict | None, name: str) -> tuple[float | None, float | None]:
    for group in ("states", "controls"):
        for d in (params or {}).get(group) or []:
            if isinstance(d, dict) and d.get("name") == name:
                return d.get("lower"), d.get("upper")
    for c in (params or {}).get("path") or []:   # a path constraint written as just this expression's name
        if isinstance(c, dict) and str(c.get("expr", "")).strip() == name:
            return c.get("lower"), c.get("upper")
    return None, None


def _dense(result: dict) -> dict | None:
    dense = pick(result, "verification.trajectory")   # the re-flight's dense points, when the solver keeps them
    return dense if isinstance(dense, dict) and dense.get("t") else None


def _against_time(name: str):
    def draw(fig, r, params):
        ax = fig.add_subplot()
        tr = r["trajectory"]
        ax.plot(floats(tr["t"]), floats(tr[name]), "o-", ms=3, lw=1, label="solution (nodes)")
        dense = _dense(r)
        if dense and dense.get(name):
            ax.plot(floats(dense["t"]), floats(dense[name]), "-", lw=1, label="re-flown (verification)")
        lo, hi = _bounds(params, name)
        for b, what in ((lo, "lower bound"), (hi, "upper bound")):
            if b is not None:
                ax.axhline(b, color="C3", ls="--", lw=1, label=what)
        ax.set_xlabel(_label("t", r) if "t" in (r.get("units") or {}) else "t (s)")
        ax.set_ylabel(_label(name, r))
        ax.legend()
    return draw


def _pair(x: str, y: str):
    def draw(fig, r, params):
        ax = fig.add_subplot()
        tr = r["trajectory"]
        ax.plot(floats(tr[x]), floats(tr[y]), "o-", ms=3, lw=1, label="solution (nodes)")
        dense = _dense(r)
        if dense and dense.get(x) and dense.get(y):
            ax.plot(floats(dense[x]), floats(dense[y]), "-", lw=1, label="re-flown (verification)")
        ax.set_xlabel(_label(x, r) if x != "t" else "t (s)")
        ax.set_ylabel(_label(y, r) if y != "t" else "t (s)")
        ax.legend()
    return draw


def _has(*names: str):
    return lambda r: all(isinstance((r.get("trajectory") or {}).get(n), list) for n in names)


def plots(result: dict) -> list[PlotDef]:
    """One plot per quantity against time, then the pairs of ``result["plots"]``; several phases:
    :func:`app.kinds.ocp.phase_plots.phase_plots`."""
    if result.get("phases"):
        from app.kinds.ocp.phase_plots import phase_plots
        return phase_plots(result)
    tr = result.get("trajectory") or {}
    if not isinstance(tr, dict) or "t" not in tr:
        return []
    out = [PlotDef(f"t-{name}", f"{name} against time", _against_time(name), _has("t", name))
           for name in tr if name != "t"][:MAX_TIME_PLOTS]
    seen = {p.name for p in out}
    for pair in result.get("plots") or []:
        if not (isinstance(pair, list) and len(pair) == 2):
            continue
        x, y = (str(v) for v in pair)
        name = f"{x}-{y}"
        if name not in seen:
            seen.add(name)
            out.append(PlotDef(name, f"{y} against {x}", _pair(x, y), _has(x, y)))
    return out
