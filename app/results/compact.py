"""The default ``GET /result`` body: the stored result with its bulkiest arrays thinned.

The stored result keeps everything; ``?include=scan`` / ``?include=samples`` ask for the full
arrays.  The intercept delta-v scan (16,161 points, 92% of the body) is thinned to every local
minimum and maximum plus a uniform subsample, so the curve keeps its shape and every minimum;
the robust Monte Carlo keeps 20 of its sample traces per design.
"""
from __future__ import annotations

import copy

import numpy as np

SCAN_POINTS = 300  # with the extrema and the finite-thrust block the default preset stays under 50 kB
TRACES = 20


def thin_curve(x: list, y: list, points: int = SCAN_POINTS) -> tuple[list, list]:
    """Every local extremum of y plus ``points`` evenly spaced samples, in order."""
    yv = np.array([np.nan if v is None else v for v in y], dtype=float)
    n = yv.size
    if n <= points:
        return list(x), list(y)
    keep = set(np.linspace(0, n - 1, points).round().astype(int).tolist())
    finite = np.isfinite(yv)
    inner = np.arange(1, n - 1)
    left, mid, right = yv[inner - 1], yv[inner], yv[inner + 1]
    with np.errstate(invalid="ignore"):
        extremum = ((mid <= left) & (mid <= right)) | ((mid >= left) & (mid >= right))
    # an edge of a NaN gap (no transfer) is kept too, so gaps stay visible
    edge = finite[inner] & (~finite[inner - 1] | ~finite[inner + 1])
    keep.update(inner[(extremum & finite[inner]) | edge].tolist())
    idx = sorted(keep)
    return [x[i] for i in idx], [y[i] for i in idx]


def compact(kind: str, result: dict, include: set[str]) -> dict:
    if kind == "intercept" and "scan" not in include:
        scan = (result.get("impulsive") or {}).get("scan")
        if scan and len(scan.get("t_man_s") or []) > SCAN_POINTS:
            result = copy.copy(result)
            result["impulsive"] = dict(result["impulsive"])
            t, dv = thin_curve(scan["t_man_s"], scan["delta_v_mps"])
            result["impulsive"]["scan"] = {"t_man_s": t, "delta_v_mps": dv, "points_stored": len(scan["t_man_s"]),
                                           "thinned": "every local minimum and maximum plus an even subsample; "
                                                      "?include=scan returns every point"}
    if kind == "robust_reentry" and "samples" not in include and isinstance(result.get("monte_carlo"), dict):
        result = copy.copy(result)
        mc = result["monte_carlo"] = dict(result["monte_carlo"])
        for design, block in mc.items():
            if isinstance(block, dict) and isinstance(block.get("sample_traces"), dict):
                block = mc[design] = dict(block)
                block["sample_traces"] = {q: v[:TRACES] for q, v in block["sample_traces"].items()}
    return result
