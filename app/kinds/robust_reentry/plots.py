"""The ``robust_reentry`` kind's plots: the two designs, the Monte Carlo envelopes and terminal states, then
the reentry kind's plots of the robust design."""
from __future__ import annotations

from app.kinds.reentry.plots import PLOTS as REENTRY_PLOTS
from app.results.plots import PlotDef, draw_band, floats, has, pick

def _designs(fig, r, params):
    ax = fig.add_subplot()
    for label, tr in (("deterministic", r["deterministic"]["trajectory"]), ("robust", r["trajectory"])):
        ax.plot(floats(tr["speed_mps"]) / 1e3, floats(tr["altitude_m"]) / 1e3, "o-", ms=2, label=label)
    ax.set_xlabel("speed (km/s)")
    ax.set_ylabel("altitude (km)")
    ax.legend()


_ENVELOPE = (("altitude_m", "altitude (km)", 1e-3), ("speed_mps", "speed (km/s)", 1e-3),
             ("heat_rate_w_m2", "heating rate (kW/m^2)", 1e-3))


def _envelopes(fig, r, params):
    mc = r["monte_carlo"]["robust"]
    env, traces = mc["envelope"], mc.get("sample_traces") or {}
    k = pick(params or {}, "robust.k_constraint") or 3.0
    t = floats(env["t_s"])
    axes = fig.subplots(3, 1, sharex=True)
    for ax, (q, label, scale) in zip(axes, _ENVELOPE):
        for trace in (traces.get(q) or [])[:300]:
            ax.plot(t, floats(trace) * scale, color="0.7", lw=0.3, alpha=0.5)
        draw_band(ax, t, env[q]["mean"], env[q]["std"], k, scale=scale)
        ax.set_ylabel(label)
    limit = pick(params or {}, "path.max_heat_rate_w_m2")
    if limit:
        axes[2].axhline(limit * 1e-3, color="C3", ls="--", label="limit")
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time (s)")


def _terminal_scatter(fig, r, params):
    a1, a2 = fig.subplots(1, 2)
    term = params.get("terminal", {}) if params else {}
    lims = pick(params or {}, "robust.sigma_limits") or {}
    for name, mc in r["monte_carlo"].items():
        ts = mc.get("terminal_samples") if isinstance(mc, dict) else None
        if not ts:
            continue
        a1.plot(floats(ts["speed_mps"]), floats(ts["altitude_m"]) / 1e3, ".", ms=1.5, alpha=0.5, label=name)
        a2.plot(floats(ts["flight_path_deg"]), floats(ts["altitude_m"]) / 1e3, ".", ms=1.5, alpha=0.5, label=name)
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


PLOTS = [
    PlotDef("designs", "Deterministic and robust designs", _designs, has("deterministic.trajectory")),
    PlotDef("envelopes", "Monte Carlo envelopes of the robust design", _envelopes,
            has("monte_carlo.robust.envelope"), size=(9, 8)),
    PlotDef("terminal_scatter", "Terminal states of the Monte Carlo samples", _terminal_scatter,
            has("monte_carlo.robust.terminal_samples"), size=(11, 4.5)),
    *REENTRY_PLOTS,
]


def plots(result: dict) -> list[PlotDef]:
    """The kind's plots (``KindSpec.plots``)."""
    return PLOTS
