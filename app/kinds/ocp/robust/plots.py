"""The plots of a robust ``ocp`` result, after the ``robust_reentry`` kind's (shared drawing in
:mod:`app.results.plots`): every state's Monte Carlo mean and ``mean +- k sigma`` envelope against time with
CADET's predicted ``mean +- k sigma`` (dashed) and the design's mean trajectory at the nodes and the declared
bounds, several phases on one time axis (a dotted line where each later phase starts); each named path constraint's value the
same way against its limit (``k`` the constraints' k of the last round); a histogram of the objective over
the draws, marked with the Monte Carlo's mean and statistic, CADET's and the deterministic twin's optimum;
a histogram of each named boundary constraint's value against its limits.  The list follows from the stored
result (``robust.monte_carlo``), so ``GET /v1/jobs/{id}/plots`` needs nothing else."""
from __future__ import annotations

from app.kinds.ocp.plots import declared_bounds, label_of
from app.results.plots import PlotDef, draw_band, draw_histogram, floats, has, pick

SIGN = {"mean_minus_k_sigma": -1.0, "mean": 0.0, "mean_plus_k_sigma": 1.0}   # the objective's statistic


def _limits(params: dict | None, group: str, name: str) -> tuple[float | None, float | None]:
    for ph in (params or {}).get("phases") or [params or {}]:      # several phases: the first declaring it
        for c in ph.get(group) or []:
            if isinstance(c, dict) and c.get("name") == name:
                return c.get("lower"), c.get("upper")
    return None, None


def _mark_limits(ax, lower, upper, *, vertical: bool = False) -> None:
    line = ax.axvline if vertical else ax.axhline
    for b, what in ((lower, "lower limit"), (upper, "upper limit")):
        if b is not None:
            line(b, color="C3", ls="--", lw=1.2, label=what)


def _phases(ax, r) -> None:
    """Several phases on one time axis: a dotted line where each later phase starts, named."""
    for ph in (r.get("phases") or [])[1:]:
        if isinstance(ph.get("t0"), (int, float)):
            ax.axvline(ph["t0"], color="0.5", ls=":", lw=1.0)
            ax.annotate(str(ph.get("name", "")), (ph["t0"], 1.0), xycoords=("data", "axes fraction"),
                        fontsize=7, ha="left", va="top", color="0.4")


def draw_cadet(ax, cadet: dict, name: str, k: float, group: str = "states") -> None:
    """CADET's ``mean +- k sigma`` of ``name`` (a state, or a named path constraint with ``group``
    "constraints"; dashed, beside the Monte Carlo's band)."""
    t, band = floats(cadet["t"]), cadet[group][name]
    mean, std = floats(band["mean"]), floats(band["std"])
    ax.plot(t, mean + k * std, color="C2", ls="--", lw=1.0, label=f"CADET mean +- {k:g} sigma", gid="cadet-upper")
    ax.plot(t, mean - k * std, color="C2", ls="--", lw=1.0, gid="cadet-lower")


def _state(name: str):
    def draw(fig, r, params):
        ax = fig.add_subplot()
        rob = r["robust"]
        env = rob["monte_carlo"]["envelope"]
        band = env["states"][name]
        k = rob.get("k") or 3.0
        draw_band(ax, env["t"], band["mean"], band["std"], k)
        if name in (pick(rob, "cadet_envelope.states") or {}):
            draw_cadet(ax, rob["cadet_envelope"], name, k)
        label: str | None = "design (nodes)"
        for ph in r.get("phases") or [r]:          # a problem posed as one phase is its own phase
            tr = ph.get("trajectory") or {}
            if isinstance(tr.get(name), list) and isinstance(tr.get("t"), list):
                ax.plot(floats(tr["t"]), floats(tr[name]), "k.", ms=3, label=label)
                label = None
        _phases(ax, r)
        phases = (params or {}).get("phases") or [params or {}]     # the bounds of the first phase declaring it
        decl = next((ph for ph in phases if any(isinstance(x, dict) and x.get("name") == name
                                                for x in ph.get("states") or [])), params or {})
        _mark_limits(ax, *declared_bounds(decl, name))
        ax.set_xlabel(label_of("t", r))
        ax.set_ylabel(label_of(name, r))
        ax.legend(fontsize=8)
    return draw


def _constraint(name: str):
    def draw(fig, r, params):
        ax = fig.add_subplot()
        rob = r["robust"]
        env = rob["monte_carlo"]["envelope"]
        band = env["constraints"][name]
        k = rob.get("k_constraints") or rob.get("k") or 3.0
        draw_band(ax, env["t"], band["mean"], band["std"], k, color="C1")
        if name in (pick(rob, "cadet_envelope.constraints") or {}):
            draw_cadet(ax, rob["cadet_envelope"], name, k, "constraints")
        _phases(ax, r)
        _mark_limits(ax, *_limits(params, "path", name))
        kept = pick(rob, f"constraints.{name}.kept_fraction")
        ax.set_xlabel(label_of("t", r))
        ax.set_ylabel(name + (f" (Monte Carlo: {100 * kept:.2f}% of flights kept it)" if kept is not None else ""))
        ax.legend(fontsize=8)
    return draw


def _objective(fig, r, params):
    ax = fig.add_subplot()
    rob = r["robust"]
    obj = rob.get("objective") or {}
    k, sign = rob.get("k") or 3.0, SIGN.get(rob.get("statistic") or "mean", 0.0)
    mean, std = obj.get("mean"), obj.get("std")
    marks = [(mean, "Monte Carlo mean", "-"), (obj.get("cadet_mean"), "CADET mean", "--")]
    if sign and mean is not None and std is not None:
        marks.append((mean + sign * k * std, f"Monte Carlo mean {'+' if sign > 0 else '-'} {k:g} std", "-."))
    marks.append((rob.get("deterministic_objective"), "deterministic optimum", ":"))
    draw_histogram(ax, rob["monte_carlo"]["samples"]["objective"], marks=marks, xlabel="objective")


def _boundary(name: str):
    def draw(fig, r, params):
        ax = fig.add_subplot()
        rob = r["robust"]
        lower, upper = _limits(params, "boundary", name)
        draw_histogram(ax, rob["monte_carlo"]["samples"]["boundary"][name], marks=[
            (lower, "lower limit", "--"), (upper, "upper limit", "--")], xlabel=name)
    return draw


def robust_plots(result: dict) -> list[PlotDef]:
    """The robust plots this result has data for (none for a deterministic one)."""
    mc = pick(result, "robust.monte_carlo") or {}
    env, drawn = mc.get("envelope") or {}, mc.get("samples") or {}
    out = [PlotDef(f"mc-state-{n}", f"{n}: Monte Carlo mean and k-sigma envelope", _state(n),
                   has(f"robust.monte_carlo.envelope.states.{n}")) for n in env.get("states") or {}]
    out += [PlotDef(f"mc-constraint-{n}", f"{n}: Monte Carlo envelope against its limit", _constraint(n),
                    has(f"robust.monte_carlo.envelope.constraints.{n}")) for n in env.get("constraints") or {}]
    if drawn.get("objective"):
        out.append(PlotDef("mc-objective", "Objective over the Monte Carlo draws", _objective,
                           has("robust.monte_carlo.samples.objective")))
    out += [PlotDef(f"mc-boundary-{n}", f"{n} over the Monte Carlo draws", _boundary(n),
                    has(f"robust.monte_carlo.samples.boundary.{n}")) for n in drawn.get("boundary") or {}]
    return out
