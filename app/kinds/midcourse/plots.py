"""The ``midcourse`` kind's plots: the Pareto front's projections and the correction times of its points."""
from __future__ import annotations

from app.results.plots import PlotDef, floats, has

_OBJ = (("delta_v_mps", "total delta-v (m/s)"), ("position_error_m", "final position error (m)"),
        ("velocity_error_mps", "final velocity error (m/s)"))


def _front_projections(fig, r, params):
    front = r["pareto_front"]
    vals = {k: floats([p[k] for p in front]) for k, _ in _OBJ}
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


PLOTS = [
    PlotDef("pareto_front", "Pareto front (three projections)", _front_projections, has("pareto_front"),
            size=(14, 4.2)),
    PlotDef("correction_times", "Correction times of the front points", _correction_times, has("pareto_front")),
]


def plots(result: dict) -> list[PlotDef]:
    """The kind's plots (``KindSpec.plots``)."""
    return PLOTS
