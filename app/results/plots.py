"""Plots of each kind's result, drawn with matplotlib's object API (``Figure``: thread-safe, no pyplot
state, no display).  Axis labels carry the API's units; the title names the job."""
from __future__ import annotations

import io
from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class PlotDef:
    name: str
    title: str
    draw: Callable[..., None]          # draw(fig, result, params)
    available: Callable[[dict], bool]  # does this result hold what the plot needs?


def _a(values) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def _get(d: dict, path: str):
    for part in path.split("."):
        if not isinstance(d, dict) or d.get(part) is None:
            return None
        d = d[part]
    return d


def _has(*paths: str) -> Callable[[dict], bool]:
    return lambda r: all(_get(r, p) is not None for p in paths)


# --- reentry family -------------------------------------------------------------------------------
def _altitude_speed(fig, r, params):
    ax = fig.add_subplot()
    tr = r["trajectory"]
    ax.plot(_a(tr["speed_mps"]) / 1e3, _a(tr["altitude_m"]) / 1e3, "o", ms=3, label="solution (nodes)")
    dense = _get(r, "verification.trajectory")
    if dense:
        ax.plot(_a(dense["speed_mps"]) / 1e3, _a(dense["altitude_m"]) / 1e3, "-", lw=1,
                label="re-propagated (verification)")
    ax.set_xlabel("speed (km/s)")
    ax.set_ylabel("altitude (km)")
    ax.legend()


def _ground_track(fig, r, params):
    ax = fig.add_subplot()
    tr = r["trajectory"]
    ax.plot(_a(tr["longitude_deg"]), _a(tr["latitude_deg"]), "o-", ms=3, label="solution")
    dense = _get(r, "verification.trajectory")
    if dense:
        ax.plot(_a(dense["longitude_deg"]), _a(dense["latitude_deg"]), "-", lw=1, label="re-propagated")
    ax.set_xlabel("longitude (deg)")
    ax.set_ylabel("latitude (deg)")
    ax.legend()


def _controls(fig, r, params):
    tr = r["trajectory"]
    a1, a2 = fig.subplots(2, 1, sharex=True)
    a1.plot(_a(tr["t_s"]), _a(tr["alpha_deg"]), "o-", ms=3)
    a1.set_ylabel("angle of attack (deg)")
    a2.plot(_a(tr["t_s"]), _a(tr["bank_deg"]), "o-", ms=3)
    a2.set_ylabel("bank angle (deg)")
    a2.set_xlabel("time (s)")


def _heating(fig, r, params):
    ax = fig.add_subplot()
    tr = r["trajectory"]
    ax.plot(_a(tr["t_s"]), _a(tr["heat_rate_w_m2"]) / 1e3, "o", ms=3, label="solution (nodes)")
    dense = _get(r, "verification.trajectory")
    if dense:
        ax.plot(_a(dense["t_s"]), _a(dense["heat_rate_w_m2"]) / 1e3, "-", lw=1, label="re-propagated")
    limit = _get(params or {}, "path.max_heat_rate_w_m2")
    if limit:
        ax.axhline(limit / 1e3, color="C3", ls="--", label="limit")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("stagnation heating rate (kW/m^2)")
    ax.legend()


def _designs(fig, r, params):
    ax = fig.add_subplot()
    for label, tr in (("deterministic", r["deterministic"]["trajectory"]), ("robust", r["trajectory"])):
        ax.plot(_a(tr["speed_mps"]) / 1e3, _a(tr["altitude_m"]) / 1e3, "o-", ms=2, label=label)
    ax.set_xlabel("speed (km/s)")
    ax.set_ylabel("altitude (km)")
    ax.legend()


_ENVELOPE = (("altitude_m", "altitude (km)", 1e-3), ("speed_mps", "speed (km/s)", 1e-3),
             ("heat_rate_w_m2", "heating rate (kW/m^2)", 1e-3))


def _envelopes(fig, r, params):
    mc = r["monte_carlo"]["robust"]
    env, traces = mc["envelope"], mc.get("sample_traces") or {}
    k = _get(params or {}, "robust.k_constraint") or 3.0
    t = _a(env["t_s"])
    axes = fig.subplots(3, 1, sharex=True)
    for ax, (q, label, scale) in zip(axes, _ENVELOPE):
        for trace in (traces.get(q) or [])[:300]:
            ax.plot(t, _a(trace) * scale, color="0.7", lw=0.3, alpha=0.5)
        mean, std = _a(env[q]["mean"]) * scale, _a(env[q]["std"]) * scale
        ax.fill_between(t, mean - k * std, mean + k * std, color="C0", alpha=0.3, label=f"mean +- {k:g} sigma")
        ax.plot(t, mean, "C0", lw=1.5, label="mean")
        ax.set_ylabel(label)
    limit = _get(params or {}, "path.max_heat_rate_w_m2")
    if limit:
        axes[2].axhline(limit * 1e-3, color="C3", ls="--", label="limit")
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time (s)")


def _terminal_scatter(fig, r, params):
    a1, a2 = fig.subplots(1, 2)
    term = params.get("terminal", {}) if params else {}
    lims = _get(params or {}, "robust.sigma_limits") or {}
    for name, mc in r["monte_carlo"].items():
        ts = mc.get("terminal_samples") if isinstance(mc, dict) else None
        if not ts:
            continue
        a1.plot(_a(ts["speed_mps"]), _a(ts["altitude_m"]) / 1e3, ".", ms=1.5, alpha=0.5, label=name)
        a2.plot(_a(ts["flight_path_deg"]), _a(ts["altitude_m"]) / 1e3, ".", ms=1.5, alpha=0.5, label=name)
    h, v, g = term.get("altitude_m"), term.get("speed_mps"), term.get("flight_path_deg")
    if h is not None and v is not None:  # the required box: the requirement +- its sigma limit
        dh, dv = lims.get("altitude_m") or 0.0, lims.get("speed_mps") or 0.0
        a1.add_patch(_box(fig, v - dv, (h - dh) / 1e3, 2 * dv, 2 * dh / 1e3))
    if h is not None and g is not None:
        dh, dg = lims.get("altitude_m") or 0.0, lims.get("flight_path_deg") or 0.0
        a2.add_patch(_box(fig, g - dg, (h - dh) / 1e3, 2 * dg, 2 * dh / 1e3))
    a1.set_xlabel("final speed (m/s)")
    a1.set_ylabel("final altitude (km)")
    a2.set_xlabel("final flight-path angle (deg)")
    a1.legend(markerscale=6, fontsize=8)


def _box(fig, x, y, w, h):
    from matplotlib.patches import Rectangle

    return Rectangle((x, y), w, h, fill=False, ec="C3", lw=1.5, ls="--", label="required +- sigma limit")


# --- midcourse ------------------------------------------------------------------------------------
_OBJ = (("delta_v_mps", "total delta-v (m/s)"), ("position_error_m", "final position error (m)"),
        ("velocity_error_mps", "final velocity error (m/s)"))


def _front_projections(fig, r, params):
    front = r["pareto_front"]
    vals = {k: _a([p[k] for p in front]) for k, _ in _OBJ}
    axes = fig.subplots(1, 3)
    for ax, (i, j, c) in zip(axes, ((0, 1, 2), (0, 2, 1), (1, 2, 0))):
        sc = ax.scatter(vals[_OBJ[i][0]], vals[_OBJ[j][0]], c=vals[_OBJ[c][0]], s=10, cmap="viridis")
        ax.set_xlabel(_OBJ[i][1])
        ax.set_ylabel(_OBJ[j][1])
        if _OBJ[j][0] == "position_error_m":
            ax.set_yscale("log")
        fig.colorbar(sc, ax=ax, label=_OBJ[c][1], shrink=0.8)


def _correction_times(fig, r, params):
    ax = fig.add_subplot()
    front = sorted(r["pareto_front"], key=lambda p: p["delta_v_mps"])
    for rank, p in enumerate(front):
        ax.plot(p["times_s"], [rank] * len(p["times_s"]), "o", ms=3, color="C0")
    ax.set_xlabel("correction time (s)")
    ax.set_ylabel("front point (sorted by total delta-v)")


# --- intercept ------------------------------------------------------------------------------------
def _delta_v_scan(fig, r, params):
    ax = fig.add_subplot()
    scan, best = r["impulsive"]["scan"], r["impulsive"]["best"]
    ax.plot(_a(scan["t_man_s"]), _a(scan["delta_v_mps"]), lw=1)
    ax.plot([best["t_man_s"]], [best["delta_v_mps"]], "r*", ms=12,
            label=f"optimum {best['delta_v_mps']:.2f} m/s at {best['t_man_s']:.1f} s")
    ax.set_xlabel("maneuver time (s)")
    ax.set_ylabel("delta-v (m/s)")
    ax.set_ylim(0, min(np.nanmax(_a(scan["delta_v_mps"])), 5 * best["delta_v_mps"]))
    ax.legend()


def _porkchop(fig, r, params):
    ax = fig.add_subplot()
    pc = r["impulsive"]["porkchop"]
    grid = _a(np.ravel(pc["delta_v_mps"])).reshape(len(pc["t_man_s"]), len(pc["t_intercept_s"]))
    lo = np.nanmin(grid)
    # clipped: the map spans orders of magnitude near degenerate transfers; show the useful band
    mesh = ax.pcolormesh(_a(pc["t_intercept_s"]), _a(pc["t_man_s"]), grid, shading="auto",
                         vmin=lo, vmax=min(np.nanpercentile(grid, 60), 4 * lo), cmap="viridis_r")
    fig.colorbar(mesh, ax=ax, label="delta-v (m/s)")
    b = pc["best"]
    ax.plot([b["t_intercept_s"]], [b["t_man_s"]], "r*", ms=12)
    ax.set_xlabel("interception time (s)")
    ax.set_ylabel("maneuver time (s)")


def _thrust_mass(fig, r, params):
    ft = r["finite_thrust"]
    tr = ft["trajectory"]
    a1, a2 = fig.subplots(2, 1, sharex=True)
    a1.plot(_a(tr["t_s"]), _a(tr["thrust_n"]), "C0", label="thrust")
    a1.set_ylabel("thrust (N)")
    along = _get(ft, "optimality.along_trajectory")
    if along and along.get("switching_function") is not None:
        tw = a1.twinx()
        tw.plot(_a(along["t_s"]), _a(along["switching_function"]), "C1", lw=0.8, label="switching function")
        tw.axhline(0, color="0.5", lw=0.5)
        tw.set_ylabel("switching function")
    a2.plot(_a(tr["t_s"]), _a(tr["mass_kg"]), "C2")
    a2.set_ylabel("mass (kg)")
    a2.set_xlabel("time (s)")


def _hill(fig, r, params):
    ax = fig.add_subplot()
    tr = r["finite_thrust"]["trajectory"]
    ax.plot(_a(tr["y_m"]) / 1e3, _a(tr["x_m"]) / 1e3, "-")
    ax.plot([0], [0], "k*", ms=10, label="target")
    ax.set_xlabel("along-track y (km)")
    ax.set_ylabel("radial x (km)")
    ax.legend()


REENTRY = [
    PlotDef("altitude_speed", "Altitude against speed", _altitude_speed, _has("trajectory.altitude_m")),
    PlotDef("ground_track", "Ground track", _ground_track, _has("trajectory.latitude_deg")),
    PlotDef("controls", "Angle of attack and bank", _controls, _has("trajectory.alpha_deg")),
    PlotDef("heating", "Heating rate", _heating, _has("trajectory.heat_rate_w_m2")),
]
PLOTS: dict[str, list[PlotDef]] = {
    "reentry": REENTRY,
    "robust_reentry": [
        PlotDef("designs", "Deterministic and robust designs", _designs, _has("deterministic.trajectory")),
        PlotDef("envelopes", "Monte Carlo envelopes of the robust design", _envelopes,
                _has("monte_carlo.robust.envelope")),
        PlotDef("terminal_scatter", "Terminal states of the Monte Carlo samples", _terminal_scatter,
                _has("monte_carlo.robust.terminal_samples")),
        *REENTRY,
    ],
    "midcourse": [
        PlotDef("pareto_front", "Pareto front (three projections)", _front_projections, _has("pareto_front")),
        PlotDef("correction_times", "Correction times of the front points", _correction_times,
                _has("pareto_front")),
    ],
    "intercept": [
        PlotDef("delta_v_scan", "Delta-v against maneuver time", _delta_v_scan, _has("impulsive.scan", "impulsive.best")),
        PlotDef("porkchop", "Porkchop map", _porkchop, _has("impulsive.porkchop.delta_v_mps")),
        PlotDef("thrust_mass", "Thrust, mass and switching function", _thrust_mass,
                _has("finite_thrust.trajectory.thrust_n")),
        PlotDef("hill_trajectory", "Relative trajectory in the target's Hill frame", _hill,
                _has("finite_thrust.trajectory.x_m")),
    ],
}

SIZES = {"pareto_front": (14, 4.2), "envelopes": (9, 8), "terminal_scatter": (11, 4.5), "controls": (8, 6),
         "thrust_mass": (8, 6)}


def plots_for(kind: str, result: dict) -> list[PlotDef]:
    from app.kinds import KINDS   # here: a kind's own plots module imports PlotDef from this one

    own = getattr(KINDS.get(kind), "plots", None)
    return [p for p in (own(result) if own is not None else PLOTS.get(kind, [])) if p.available(result)]


def render(plot: PlotDef, *, result: dict, params: dict, title: str, fmt: str, dpi: int = 100) -> bytes:
    """One plot as PNG or SVG bytes."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=SIZES.get(plot.name, (8, 5)), dpi=dpi, layout="constrained")
    plot.draw(fig, result, params)
    for ax in fig.axes:
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"{plot.title}: {title}")
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, metadata={"Date": None} if fmt == "svg" else None)
    return buf.getvalue()
