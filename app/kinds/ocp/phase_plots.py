"""Plots of a multi-phase ``ocp`` result: every quantity against one time axis, the phases in turn.

Each quantity that some phase reports is drawn phase after phase on the same axes (a phase that
does not have it leaves a gap), the boundaries between phases marked by vertical lines labelled
with the next phase's name; each pair ``[x, y]`` of ``plots`` is drawn phase by phase too.
"""
from __future__ import annotations

from app.results.plots import PlotDef, floats

MAX_TIME_PLOTS = 300


def _phases(result: dict) -> list[dict]:
    return [p for p in result.get("phases") or [] if isinstance(p, dict) and isinstance(p.get("trajectory"), dict)]


def _label(name: str, result: dict) -> str:
    unit = (result.get("units") or {}).get(name)
    return f"{name} ({unit})" if unit else name


def _boundaries(ax, phases: list[dict]) -> None:
    top = ax.get_ylim()[1]
    for p in phases[1:]:
        t0 = p.get("t0")
        if t0 is None:
            continue
        ax.axvline(t0, color="0.4", ls=":", lw=1)
        ax.text(t0, top, f" {p['name']}", rotation=90, va="top", ha="left", fontsize=8, color="0.3")


def _against_time(name: str):
    def draw(fig, r, params):
        ax = fig.add_subplot()
        phases = _phases(r)
        for i, p in enumerate(phases):
            tr = p["trajectory"]
            if isinstance(tr.get(name), list):
                ax.plot(floats(tr["t"]), floats(tr[name]), "o-", ms=2, lw=1, color=f"C{i % 10}", label=p["name"])
        _boundaries(ax, phases)
        ax.set_xlabel("t (s)")
        ax.set_ylabel(_label(name, r))
        ax.legend(title="phase")
    return draw


def _pair(x: str, y: str):
    def draw(fig, r, params):
        ax = fig.add_subplot()
        for i, p in enumerate(_phases(r)):
            tr = p["trajectory"]
            if isinstance(tr.get(x), list) and isinstance(tr.get(y), list):
                ax.plot(floats(tr[x]), floats(tr[y]), "o-", ms=2, lw=1, color=f"C{i % 10}", label=p["name"])
        ax.set_xlabel(_label(x, r) if x != "t" else "t (s)")
        ax.set_ylabel(_label(y, r) if y != "t" else "t (s)")
        ax.legend(title="phase")
    return draw


def _has(*names: str):
    return lambda r: any(all(isinstance(p["trajectory"].get(n), list) for n in names) for p in _phases(r))


def phase_plots(result: dict) -> list[PlotDef]:
    """One plot per quantity against time (the phases on one axis), then the ``plots`` pairs."""
    names: list[str] = []
    for p in _phases(result):
        names += [n for n in p["trajectory"] if n != "t" and n not in names]
    out = [PlotDef(f"t-{n}", f"{n} against time (all phases)", _against_time(n), _has("t", n))
           for n in names][:MAX_TIME_PLOTS]
    seen = {p.name for p in out}
    for pair in result.get("plots") or []:
        if isinstance(pair, list) and len(pair) == 2:
            x, y = (str(v) for v in pair)
            if f"{x}-{y}" not in seen:
                seen.add(f"{x}-{y}")
                out.append(PlotDef(f"{x}-{y}", f"{y} against {x} (all phases)", _pair(x, y), _has(x, y)))
    return out
