"""The ``reentry`` kind's plots (drawn by :func:`app.results.plots.render`); the robust kind shows them too."""
from __future__ import annotations

from app.results.plots import PlotDef, floats, has, pick

def _altitude_speed(fig, r, params):
    ax = fig.add_subplot()
    tr = r["trajectory"]
    ax.plot(floats(tr["speed_mps"]) / 1e3, floats(tr["altitude_m"]) / 1e3, "o", ms=3, label="solution (nodes)")
    dense = pick(r, "verification.trajectory")
    if dense:
        ax.plot(floats(dense["speed_mps"]) / 1e3, floats(dense["altitude_m"]) / 1e3, "-", lw=1,
                label="re-propagated (verification)")
    ax.set_xlabel("speed (km/s)")
    ax.set_ylabel("altitude (km)")
    ax.legend()


def _ground_track(fig, r, params):
    ax = fig.add_subplot()
    tr = r["trajectory"]
    ax.plot(floats(tr["longitude_deg"]), floats(tr["latitude_deg"]), "o-", ms=3, label="solution")
    dense = pick(r, "verification.trajectory")
    if dense:
        ax.plot(floats(dense["longitude_deg"]), floats(dense["latitude_deg"]), "-", lw=1, label="re-propagated")
    ax.set_xlabel("longitude (deg)")
    ax.set_ylabel("latitude (deg)")
    ax.legend()


def _controls(fig, r, params):
    tr = r["trajectory"]
    a1, a2 = fig.subplots(2, 1, sharex=True)
    a1.plot(floats(tr["t_s"]), floats(tr["alpha_deg"]), "o-", ms=3)
    a1.set_ylabel("angle of attack (deg)")
    a2.plot(floats(tr["t_s"]), floats(tr["bank_deg"]), "o-", ms=3)
    a2.set_ylabel("bank angle (deg)")
    a2.set_xlabel("time (s)")


def _heating(fig, r, params):
    ax = fig.add_subplot()
    tr = r["trajectory"]
    ax.plot(floats(tr["t_s"]), floats(tr["heat_rate_w_m2"]) / 1e3, "o", ms=3, label="solution (nodes)")
    dense = pick(r, "verification.trajectory")
    if dense:
        ax.plot(floats(dense["t_s"]), floats(dense["heat_rate_w_m2"]) / 1e3, "-", lw=1, label="re-propagated")
    limit = pick(params or {}, "path.max_heat_rate_w_m2")
    if limit:
        ax.axhline(limit / 1e3, color="C3", ls="--", label="limit")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("stagnation heating rate (kW/m^2)")
    ax.legend()


PLOTS = [
    PlotDef("altitude_speed", "Altitude against speed", _altitude_speed, has("trajectory.altitude_m")),
    PlotDef("ground_track", "Ground track", _ground_track, has("trajectory.latitude_deg")),
    PlotDef("controls", "Angle of attack and bank", _controls, has("trajectory.alpha_deg"), size=(8, 6)),
    PlotDef("heating", "Heating rate", _heating, has("trajectory.heat_rate_w_m2")),
]


def plots(result: dict) -> list[PlotDef]:
    """The kind's plots (``KindSpec.plots``); :func:`app.results.plots.plots_for` keeps those a result can draw."""
    return PLOTS
