"""The ``intercept`` kind's plots: the impulsive delta-v scan and porkchop map, the finite-thrust history
and the relative trajectory."""
from __future__ import annotations

import numpy as np

from app.results.plots import PlotDef, floats, has, pick

def _delta_v_scan(fig, r, params):
    ax = fig.add_subplot()
    scan, best = r["impulsive"]["scan"], r["impulsive"]["best"]
    ax.plot(floats(scan["t_man_s"]), floats(scan["delta_v_mps"]), lw=1)
    ax.plot([best["t_man_s"]], [best["delta_v_mps"]], "r*", ms=12,
            label=f"optimum {best['delta_v_mps']:.2f} m/s at {best['t_man_s']:.1f} s")
    ax.set_xlabel("maneuver time (s)")
    ax.set_ylabel("delta-v (m/s)")
    ax.set_ylim(0, min(np.nanmax(floats(scan["delta_v_mps"])), 5 * best["delta_v_mps"]))
    ax.legend()


def _porkchop(fig, r, params):
    ax = fig.add_subplot()
    pc = r["impulsive"]["porkchop"]
    grid = floats(np.ravel(pc["delta_v_mps"])).reshape(len(pc["t_man_s"]), len(pc["t_intercept_s"]))
    lo = np.nanmin(grid)
    # clipped: the map spans orders of magnitude near degenerate transfers; show the useful band
    mesh = ax.pcolormesh(floats(pc["t_intercept_s"]), floats(pc["t_man_s"]), grid, shading="auto",
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
    a1.plot(floats(tr["t_s"]), floats(tr["thrust_n"]), "C0", label="thrust")
    a1.set_ylabel("thrust (N)")
    along = pick(ft, "optimality.along_trajectory")
    if along and along.get("switching_function") is not None:
        tw = a1.twinx()
        tw.plot(floats(along["t_s"]), floats(along["switching_function"]), "C1", lw=0.8, label="switching function")
        tw.axhline(0, color="0.5", lw=0.5)
        tw.set_ylabel("switching function")
    a2.plot(floats(tr["t_s"]), floats(tr["mass_kg"]), "C2")
    a2.set_ylabel("mass (kg)")
    a2.set_xlabel("time (s)")


def _hill(fig, r, params):
    ax = fig.add_subplot()
    tr = r["finite_thrust"]["trajectory"]
    ax.plot(floats(tr["y_m"]) / 1e3, floats(tr["x_m"]) / 1e3, "-")
    ax.plot([0], [0], "k*", ms=10, label="target")
    ax.set_xlabel("along-track y (km)")
    ax.set_ylabel("radial x (km)")
    ax.legend()


PLOTS = [
    PlotDef("delta_v_scan", "Delta-v against maneuver time", _delta_v_scan, has("impulsive.scan", "impulsive.best")),
    PlotDef("porkchop", "Porkchop map", _porkchop, has("impulsive.porkchop.delta_v_mps")),
    PlotDef("thrust_mass", "Thrust, mass and switching function", _thrust_mass,
            has("finite_thrust.trajectory.thrust_n"), size=(8, 6)),
    PlotDef("hill_trajectory", "Relative trajectory in the target's Hill frame", _hill,
            has("finite_thrust.trajectory.x_m")),
]


def plots(result: dict) -> list[PlotDef]:
    """The kind's plots (``KindSpec.plots``)."""
    return PLOTS
