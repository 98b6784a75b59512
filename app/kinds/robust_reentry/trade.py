"""The ``robust_reentry`` kind's key numbers and what a study of it charts (app.kinds.trade).

Every number says where it comes from: ``mc.`` the Monte Carlo flown over the robust design's controls,
``cadet.`` CADET's covariance prediction (what the NLP optimized), ``deterministic.`` the deterministic
optimum it gave up.  A study draws the Monte Carlo and CADET figures of one quantity on one panel, so the
gap between promise and measurement is what the reader sees.
"""
from __future__ import annotations

from app.kinds.trade import TradeOutput

ROBUST = "robust crossrange (mean - k sigma)"
SPREAD = "final latitude spread (1 sigma)"


def key_numbers(result: dict) -> dict:
    objective = result["objective"]
    mc = (result.get("monte_carlo") or {}).get("robust") or {}
    mc_objective = mc.get("objective") or {}
    kept = mc.get("heat_rate_kept_fraction")
    out = {"mc.objective_deg": mc_objective.get("mean_minus_k_std"),
           "cadet.objective_deg": objective.get("cadet_value"),
           "mc.std_latitude_deg": mc_objective.get("std"), "cadet.sigma_latitude_deg": objective.get("sigma_latitude_deg"),
           "mc.mean_latitude_deg": mc_objective.get("mean"), "cadet.mean_latitude_deg": objective.get("mean_latitude_deg"),
           "mc.heat_kept_percent": None if kept is None else 100.0 * kept,
           "deterministic.objective_deg": ((result.get("deterministic") or {}).get("objective") or {}).get("value"),
           "tf_s": result.get("tf_s"), "mc.samples": mc.get("samples"),
           "iterations": (result.get("solver") or {}).get("iterations")}
    confirmed = (result.get("confirmation") or {}).get("agrees")
    if isinstance(confirmed, bool):
        out["confirmed"] = confirmed
    return out


def trade_outputs(result: dict, params: dict | None = None) -> list[TradeOutput]:
    return [TradeOutput("mc.objective_deg", "Monte Carlo: mean - k std", "deg", panel=ROBUST),
            TradeOutput("cadet.objective_deg", "CADET: mean - k sigma", "deg", panel=ROBUST),
            TradeOutput("mc.std_latitude_deg", "Monte Carlo std", "deg", panel=SPREAD),
            TradeOutput("cadet.sigma_latitude_deg", "CADET sigma", "deg", panel=SPREAD),
            TradeOutput("mc.heat_kept_percent", "Monte Carlo: heating limit kept", "% of samples"),
            TradeOutput("deterministic.objective_deg", "deterministic crossrange", "deg"),
            TradeOutput("tf_s", "flight time", "s")]
