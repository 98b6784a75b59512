"""What a robust ``ocp`` result adds to its key numbers, its CSV tables and a study's chart: the price of
robustness as a curve over k or over a sigma.

Every number says where it comes from, as the ``robust_reentry`` kind's do: ``mc.`` the Monte Carlo flown
over the design's open-loop controls, ``cadet.`` CADET's first-order prediction (what the robust NLP
optimized), ``deterministic.`` the twin's optimum it gave up.  A study draws the Monte Carlo and CADET
figures of one quantity on one panel, so the gap between promise and measurement is what the reader sees.
"""
from __future__ import annotations

from app.kinds.trade import TradeOutput
from app.results.tables import Picker

SIGN = {"mean_minus_k_sigma": -1.0, "mean": 0.0, "mean_plus_k_sigma": 1.0}   # the objective's statistic


def _statistic(mean, std, k, sign):
    if mean is None or std is None or k is None:
        return None
    return mean + sign * k * std


def robust_key_numbers(result: dict) -> dict:
    """The robust block's numbers by source (module docstring); {} for a deterministic result."""
    rob = result.get("robust")
    if not isinstance(rob, dict):
        return {}
    obj = rob.get("objective") or {}
    k, sign = rob.get("k"), SIGN.get(rob.get("statistic") or "mean", 0.0)
    det = rob.get("deterministic_objective")
    mc = _statistic(obj.get("mean"), obj.get("std"), k, sign)
    out = {"robust.k": k, "robust.k_constraints": rob.get("k_constraints"),
           "robust.sigma_factor": rob.get("sigma_factor"), "mc.samples": rob.get("samples"),
           "mc.objective": mc, "cadet.objective": rob.get("robust_objective"),
           "mc.objective_mean": obj.get("mean"), "cadet.objective_mean": obj.get("cadet_mean"),
           "mc.objective_std": obj.get("std"), "cadet.objective_std": obj.get("cadet_std"),
           "deterministic.objective": det,
           "mc.cost_of_robustness": None if mc is None or det is None else mc - det,
           "cadet.cost_of_robustness": rob.get("cost_of_robustness"),
           "confirmed": rob.get("confirmed")}
    for name, c in (rob.get("constraints") or {}).items():
        kept = (c or {}).get("kept_fraction")
        out[f"mc.kept_percent.{name}"] = None if kept is None else 100.0 * kept
    return out


def robust_trade_outputs(result: dict, *, words: str, unit: str) -> list[TradeOutput]:
    """The panels of a study over k or a sigma: the robust objective, its spread and the price of robustness,
    each the Monte Carlo's beside CADET's, and each named constraint's kept share."""
    rob = result.get("robust") or {}
    statistic = (rob.get("statistic") or "mean").replace("_", " ")
    robust, spread, price = f"robust objective: {statistic} ({words})", "objective spread (1 sigma)", \
        "price of robustness (robust - deterministic)"
    out = [TradeOutput("mc.objective", "Monte Carlo", unit, panel=robust),
           TradeOutput("cadet.objective", "CADET (the design's NLP)", unit, panel=robust),
           TradeOutput("deterministic.objective", "deterministic optimum", unit, panel=robust),
           TradeOutput("mc.cost_of_robustness", "Monte Carlo", unit, panel=price),
           TradeOutput("cadet.cost_of_robustness", "CADET", unit, panel=price),
           TradeOutput("mc.objective_std", "Monte Carlo std", unit, panel=spread),
           TradeOutput("cadet.objective_std", "CADET sigma", unit, panel=spread)]
    out += [TradeOutput(f"mc.kept_percent.{n}", f"Monte Carlo: {n} kept", "% of samples")
            for n in rob.get("constraints") or {}]
    return out


def _envelope(r: dict) -> dict | None:
    env = (((r.get("robust") or {}).get("monte_carlo") or {}).get("envelope"))
    if not isinstance(env, dict) or not env.get("t"):
        return None
    cols: dict = {"t": env["t"]}
    states = env.get("states") or {}
    for group, prefix in ((states, ""), (env.get("constraints") or {}, "path.")):
        for name, band in group.items():
            key = f"{prefix}{name}" if prefix and name in states else name
            cols[f"{key}.mean"], cols[f"{key}.std"] = band["mean"], band["std"]
    return cols


def _samples(r: dict) -> dict | None:
    drawn = (((r.get("robust") or {}).get("monte_carlo") or {}).get("samples"))
    if not isinstance(drawn, dict) or not drawn.get("objective"):
        return None
    return {"sample": list(range(len(drawn["objective"]))), "objective": drawn["objective"],
            **{f"boundary.{n}": v for n, v in (drawn.get("boundary") or {}).items()}}


def _rounds(r: dict) -> dict | None:
    rounds = (r.get("robust") or {}).get("rounds")
    if not rounds:
        return None
    names = list(dict.fromkeys(n for x in rounds for n in x.get("kept_fractions") or {}))
    return {"round": [x.get("round") for x in rounds], "k_constraints": [x.get("k_constraints") for x in rounds],
            "objective": [x.get("objective") for x in rounds], "confirmed": [x.get("confirmed") for x in rounds],
            **{f"kept_fraction.{n}": [(x.get("kept_fractions") or {}).get(n) for x in rounds] for n in names}}


# KindSpec.tables of ocp: the Monte Carlo's envelope over time (one row per kept node time), its draws (one row
# per kept draw: the objective and each named boundary value) and the confirmation rounds.
ROBUST_TABLES: dict[str, Picker] = {"robust_envelope": _envelope, "robust_samples": _samples,
                                    "robust_rounds": _rounds}
