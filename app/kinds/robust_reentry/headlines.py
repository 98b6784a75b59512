"""The ``robust_reentry`` kind's headline numbers (app.kinds.headlines): the robust crossrange, the
Monte Carlo's share of samples that kept the heating limit (the number the case is about) against
the share the confirmation accepts, and the deterministic optimum it gave up for that."""
from __future__ import annotations

from app.kinds.headlines import Headline, fmt, number

OBJECTIVE = "robust crossrange (mean - k sigma of the final latitude)"


def _heat_acceptance(result: dict) -> float | None:
    rounds = (result.get("confirmation") or {}).get("rounds") or []
    heat = ((rounds[-1].get("constraints") or {}).get("heat_rate") or {}) if rounds else {}
    return heat.get("acceptance")


def headlines(result: dict, params: dict | None = None) -> list[Headline]:
    objective = result["objective"]
    out = [number(OBJECTIVE, objective.get("value"), objective.get("unit") or "deg")]
    robust = (result.get("monte_carlo") or {}).get("robust") or {}
    kept, samples = robust.get("heat_rate_kept_fraction"), robust.get("samples")
    if kept is not None and samples:
        acceptance = _heat_acceptance(result)
        text = f"Monte Carlo: heating kept in {100 * kept:.2f}% of {fmt(int(samples))} samples"
        held = None if acceptance is None else kept >= acceptance
        if acceptance is not None:
            text += f" (accepted from {100 * acceptance:.2f}%)"
        out.append(Headline("Monte Carlo heating kept", round(100 * kept, 4), "% of samples",
                            verdict=None if held is None else ("kept" if held else "not kept"), good=held, text=text))
    det = (result.get("deterministic") or {}).get("objective") or {}
    if det.get("value") is not None:
        out.append(number("deterministic crossrange", det["value"], det.get("unit") or "deg"))
    return out
