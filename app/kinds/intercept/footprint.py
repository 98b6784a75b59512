"""What an ``intercept`` job takes and keeps: its cost in :mod:`app.service.quota`'s work units, its
porkchop as a CSV table, and its default result body (:mod:`app.results.compact`: the delta-v scan,
16,161 points and 92% of the preset's body, thinned)."""
from __future__ import annotations

import copy

from app.results.compact import SCAN_POINTS, thin_curve


def cost(params: dict) -> float:
    """Scan and porkchop points / 100, plus 200 per finite-thrust mesh (1 + max_refinements), twice that
    with a free final time."""
    total = 0.0
    methods = params.get("methods") or []
    if "impulsive" in methods:
        scan = params.get("scan") or {}
        start = float(scan.get("t_start_s") or 0.0)
        end = scan.get("t_end_s") or params.get("intercept_time_s") or 0.0
        step = float(scan.get("step_s") or 1.0)
        total += max(0.0, float(end) - start) / step / 100.0
        porkchop = params.get("porkchop") or {}
        if porkchop.get("enabled"):
            total += float(porkchop.get("t_man_points", 0)) * float(porkchop.get("t_intercept_points", 0)) / 100.0
    if "finite_thrust" in methods:
        meshes = 1.0 + float((params.get("finite_thrust") or {}).get("max_refinements", 3))
        total += 200.0 * meshes * (2.0 if params.get("free_final_time") else 1.0)
    return total


def porkchop_table(result: dict) -> dict[str, list] | None:
    """The porkchop grid as one row per (maneuver time, intercept time)."""
    pc = (result.get("impulsive") or {}).get("porkchop")
    if not pc:
        return None
    rows = [(tm, ti, pc["delta_v_mps"][i][j]) for i, tm in enumerate(pc["t_man_s"])
            for j, ti in enumerate(pc["t_intercept_s"])]
    return {"t_man_s": [a for a, _, _ in rows], "t_intercept_s": [b for _, b, _ in rows],
            "delta_v_mps": [c for _, _, c in rows]}


def compact(result: dict, include: set[str]) -> dict:
    """The scan thinned to every local minimum and maximum plus an even subsample unless ``scan`` is asked
    for, so the curve keeps its shape and every minimum."""
    scan = (result.get("impulsive") or {}).get("scan")
    if "scan" in include or not scan or len(scan.get("t_man_s") or []) <= SCAN_POINTS:
        return result
    result = copy.copy(result)
    result["impulsive"] = dict(result["impulsive"])
    t, dv = thin_curve(scan["t_man_s"], scan["delta_v_mps"])
    result["impulsive"]["scan"] = {"t_man_s": t, "delta_v_mps": dv, "points_stored": len(scan["t_man_s"]),
                                   "thinned": "every local minimum and maximum plus an even subsample; "
                                              "?include=scan returns every point"}
    return result
