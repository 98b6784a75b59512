"""The ``reentry`` kind's key numbers and what a study of it charts (app.kinds.trade): the objective in
words with its unit, the flight time, the final state (the fixed parts drop out of a study's plot as
constant) and the dense re-propagation's peaks; iterations and the limits' verdicts in the table only."""
from __future__ import annotations

from app.kinds.reentry.headlines import OBJECTIVE_WORDS
from app.kinds.trade import TradeOutput, name_unit

FINAL = ("latitude_deg", "longitude_deg", "altitude_m", "speed_mps", "flight_path_deg", "heading_deg")
# key number -> (words, unit) of the dense re-propagation's peaks (verification.max_*)
PEAKS = {"peak_heat_rate_w_m2": ("max_heat_rate_w_m2", "peak heating rate", "W/m^2"),
         "peak_dynamic_pressure_pa": ("max_dynamic_pressure_pa", "peak dynamic pressure", "Pa"),
         "peak_load_factor": ("max_load_factor", "peak load factor", "g")}


def key_numbers(result: dict) -> dict:
    """The objective (in ``objective.unit``), the flight time, the final state, the peaks of the dense
    re-propagation, NLP iterations, and whether the path limits and terminal conditions held there."""
    v = result.get("verification") or {}
    out = {"objective": result["objective"]["value"], "tf_s": result["tf_s"],
           **{f"final.{k}": (result.get("final") or {}).get(k) for k in FINAL},
           **{key: v.get(field) for key, (field, _, _) in PEAKS.items() if v.get(field) is not None},
           "iterations": (result.get("solver") or {}).get("iterations")}
    for verdict in ("limits_held", "terminal_held"):
        if isinstance(v.get(verdict), bool):
            out[verdict] = v[verdict]
    return out


def trade_outputs(result: dict, params: dict | None = None) -> list[TradeOutput]:
    """The objective, the flight time, the peaks, then the final state (a study drops the fixed parts,
    and the final latitude of a crossrange study, the objective itself)."""
    objective = result["objective"]
    name = objective.get("name") or "objective"
    out = [TradeOutput("objective", OBJECTIVE_WORDS.get(name, name), objective.get("unit") or ""),
           TradeOutput("tf_s", "flight time", "s")]
    out += [TradeOutput(key, words, unit) for key, (_, words, unit) in PEAKS.items()]
    return out + [TradeOutput(f"final.{k}", "final " + k.rsplit("_", 1)[0].replace("_", " "), name_unit(k))
                  for k in FINAL]
