"""The ``midcourse`` kind's headline numbers (app.kinds.headlines): the front's size and its two ends
(the cheapest correction and the most accurate one), against the miss left uncorrected."""
from __future__ import annotations

from app.kinds.headlines import Headline, fmt, number


def headlines(result: dict, params: dict | None = None) -> list[Headline]:
    front = [p for p in result.get("pareto_front") or [] if p.get("delta_v_mps") is not None]
    out = [number("Pareto front", len(front), "points")]
    if front:
        cheap = min(front, key=lambda p: p["delta_v_mps"])
        exact = min(front, key=lambda p: p.get("position_error_m") or float("inf"))
        out.append(Headline("best delta-v", cheap["delta_v_mps"], "m/s",
                            text=f"best delta-v {fmt(cheap['delta_v_mps'])} m/s (final position error "
                                 f"{fmt(cheap.get('position_error_m'))} m)"))
        out.append(Headline("best position error", exact.get("position_error_m"), "m",
                            text=f"best position error {fmt(exact.get('position_error_m'))} m (delta-v "
                                 f"{fmt(exact['delta_v_mps'])} m/s)"))
    miss = (result.get("uncorrected") or {}).get("position_error_m")
    if miss is not None:
        out.append(number("uncorrected position error", miss, "m"))
    if result.get("hypervolume") is not None:
        out.append(number("hypervolume", result["hypervolume"], "(0-1)"))
    return out
