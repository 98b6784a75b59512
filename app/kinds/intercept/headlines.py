"""The ``intercept`` kind's headline numbers (app.kinds.headlines): per method that ran, the delta-v
and propellant it costs, and the miss distance its re-propagation found."""
from __future__ import annotations

from app.kinds.headlines import Headline, fmt

METHOD_WORDS = {"impulsive": "impulsive (one burn)", "finite_thrust": "finite thrust"}


def headlines(result: dict, params: dict | None = None) -> list[Headline]:
    out = []
    for row in result.get("comparison") or []:
        method = METHOD_WORDS.get(row["method"], row["method"])
        text = f"{method}: delta-v {fmt(row.get('delta_v_mps'), 6)} m/s, propellant {fmt(row.get('fuel_kg'), 5)} kg"
        if row.get("miss_distance_m") is not None:
            text += f", miss {fmt(row['miss_distance_m'], 2)} m"
        out.append(Headline(f"{row['method']} delta-v", row.get("delta_v_mps"), "m/s", text=text))
    if result.get("comparison"):
        out.append(Headline("interception time", result["comparison"][0].get("tf_s"), "s",
                            text=f"interception at t = {fmt(result['comparison'][0].get('tf_s'), 6)} s"))
    return out
