"""The ``ocp`` kind's headline numbers (app.kinds.headlines): the objective as the problem wrote it
(sense and expression, with the unit when the expression is a state or the final time), and whether the
dense re-flight kept every limit and met every terminal condition (a re-flight interval by interval, for
dynamics that amplify errors, says so)."""
from __future__ import annotations

from app.kinds.headlines import Headline, number, terminal_headline, verdict


def objective_words(params: dict | None) -> tuple[str, str]:
    """(words, unit) of the objective: "minimize tf" in s; a state's own unit when it is one state."""
    objective = (params or {}).get("objective") or {}
    integrand = objective.get("integrand")
    if isinstance(integrand, dict):          # several phases: an integrand per phase
        integrand = " + ".join(f"{v} over {k}" for k, v in integrand.items())
    expr = objective.get("expr") or ("integral of " + str(integrand) if integrand else "")
    sense = objective.get("sense") or "minimize"
    states = list((params or {}).get("states") or [])
    for ph in (params or {}).get("phases") or []:     # several phases: each declares its states
        states += ph.get("states") or [] if isinstance(ph, dict) else []
    units = {s.get("name"): s.get("unit") or "" for s in states}
    final = expr[len("final("):-1] if expr.startswith("final(") and expr.endswith(")") else None
    final = final.split(",")[0].strip() if final else None    # final(h, "coast"): the state h
    unit = "s" if expr in ("tf", "t_f") else units.get(final or expr, "")
    return (f"{sense} {expr}" if expr else sense), unit


def headlines(result: dict, params: dict | None = None) -> list[Headline]:
    words, unit = objective_words(params)
    out = [number(f"objective ({words})", result["objective"].get("value"), unit, digits=6)]
    if result.get("tf") is not None and unit != "s":
        out.append(number("final time", result["tf"], "s", digits=5))
    v = result.get("verification") or {}
    if isinstance(v.get("limits_held"), bool):
        out.append(verdict("path limits", held=v["limits_held"], value=None, unit="",
                           detail=f"on the dense re-flight (tolerance {v.get('limit_tolerance')})"))
    outside = {k: c for k, c in (v.get("controls") or {}).items() if isinstance(c, dict) and not c.get("held")}
    if outside:      # an LGL control's polynomial leaving its bounds between the nodes (issue 35 item 6)
        name, c = max(outside.items(), key=lambda kv: kv[1].get("excursion") or 0.0)
        out.append(verdict("controls within bounds", held=False, value=c.get("worst_value"), unit="",
                           detail=f"{name} = {c.get('worst_value')} at t = {c.get('worst_t')} s between the nodes "
                                  "(held at the nodes)"))
    terminal = terminal_headline(v)
    if terminal:
        out.append(terminal)
    optimality = v.get("optimality")
    if isinstance(optimality, dict) and isinstance(optimality.get("held"), bool):
        failed = [k for k, c in (optimality.get("checks") or {}).items() if not c.get("held")]
        out.append(verdict("optimality", held=optimality["held"], value=None, unit="",
                           detail=optimality.get("message") or "",
                           words=("verified", f"not verified: {', '.join(failed)}")))
    search = result.get("search")
    if isinstance(search, dict):      # several starts: how many found what
        optima = search.get("distinct_optima") or []
        out.append(Headline(name="starts", value=search.get("succeeded"), text=(
            f"starts: best of {search.get('starts')} (start {search.get('best_start')}), {search.get('succeeded')} "
            f"succeeded, {len(optima)} distinct optim{'um' if len(optima) == 1 else 'a'}")))
    if isinstance(v.get("agrees"), bool):
        # dynamics that amplify errors: each interval flown from its own node (solvers/ocp/growth.py)
        label = "re-flight interval by interval" if v.get("mode") == "interval_by_interval" else "re-flight"
        out.append(verdict(label, held=v["agrees"], value=v.get("max_state_difference_scaled_overall"),
                           unit="", detail=v.get("message") or "", words=("agrees", "disagrees")))
    return out
