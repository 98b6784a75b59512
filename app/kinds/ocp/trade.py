"""What a study of ``ocp`` problems charts (app.kinds.trade): the objective as the problem wrote it, the
final time, each state's final value and each optimized parameter, in the units the problem declared;
and a swept parameter named as the problem names it ("final value of h [m]" for ``states.1.final``)."""
from __future__ import annotations

from app.kinds.ocp.headlines import objective_words
from app.kinds.ocp.robust.trade import robust_trade_outputs
from app.kinds.trade import TradeOutput

# A swept field of a declaration, in words; the unit is the declared variable's.
FIELD_WORDS = {"final": "final value of {}", "initial": "initial value of {}", "lower": "lower bound of {}",
               "upper": "upper bound of {}", "guess": "guess of {}", "scale": "scale of {}"}
TIME_WORDS = {"final": "final time", "initial": "initial time", "final_lower": "lower bound of tf",
              "final_upper": "upper bound of tf", "final_guess": "guess of tf", "initial_lower": "lower bound of t0",
              "initial_upper": "upper bound of t0", "initial_guess": "guess of t0"}


def trade_outputs(result: dict, params: dict | None) -> list[TradeOutput]:
    """The objective, tf (unless it is the objective), each state's final value and each parameter;
    the study drops the ones that are the same at every point (a fixed final value)."""
    words, unit = objective_words(params)
    units = result.get("units") or {}
    # a robust design: the Monte Carlo's and CADET's objective side by side (the NLP's objective is CADET's)
    out = robust_trade_outputs(result, words=words, unit=unit) if result.get("robust") else \
        [TradeOutput("objective", f"objective ({words})", unit)]
    if words.split(" ", 1)[-1] not in ("tf", "t_f"):
        out.append(TradeOutput("tf", "final time", "s"))
    out += [TradeOutput(f"final.{name}", f"final {name}", units.get(name) or "") for name in result.get("final") or {}]
    out += [TradeOutput(f"parameters.{name}", name, units.get(name) or "") for name in result.get("parameters") or {}]
    return out


def _element(group: list, part: str) -> dict | None:
    if part.isdigit() and int(part) < len(group):
        item = group[int(part)]
    else:
        item = next((g for g in group if isinstance(g, dict) and g.get("name") == part), None)
    return item if isinstance(item, dict) else None


def swept_label(params: dict, path: str) -> tuple[str, str]:
    """``states.1.final`` -> ("final value of h", "m"); ``time.final`` -> ("final time", "s");
    ``robust.k`` -> ("k (sigmas of margin)", ""); ``uncertainty.parameters.CdA.sigma`` -> ("sigma of CdA", "");
    ``phases.coast.time.final_upper`` -> ("coast: upper bound of tf", "s"); ``constants.g`` -> ("g", "");
    anything else: the path, no unit."""
    parts = path.split(".")
    scope, prefix = params, ""
    if len(parts) > 2 and parts[0] == "phases":
        phase = _element(params.get("phases") or [], parts[1])
        if phase is None:
            return path, ""
        scope, prefix, parts = phase, f"{phase.get('name', parts[1])}: ", parts[2:]
    if len(parts) == 2 and parts[0] == "time" and parts[1] in TIME_WORDS:
        return prefix + TIME_WORDS[parts[1]], "s"
    if len(parts) == 2 and parts[0] == "constants":
        return prefix + parts[1], ""
    if parts in (["robust", "k"], ["robust", "monte_carlo", "sigma_factor"]):
        return ("k (sigmas of margin)" if parts[1] == "k" else "Monte Carlo sigmas over the design's"), ""
    if len(parts) == 4 and parts[:2] == ["uncertainty", "parameters"] and parts[3] in ("sigma", "lower", "upper"):
        return f"{parts[3]} of {parts[2]}", ""
    if len(parts) == 4 and parts[:2] == ["uncertainty", "initial"] and parts[3] == "sigma":
        item = _element(params.get("states") or [], parts[2])
        return f"initial sigma of {parts[2]}", (item or {}).get("unit") or ""
    if len(parts) == 3 and parts[0] in ("states", "controls", "parameters") and parts[2] in FIELD_WORDS:
        item = _element(scope.get(parts[0]) or [], parts[1])
        if item is not None:
            return prefix + FIELD_WORDS[parts[2]].format(item.get("name", parts[1])), item.get("unit") or ""
    return path, ""
