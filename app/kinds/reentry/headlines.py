"""The ``reentry`` kind's headline numbers (app.kinds.headlines): the objective in words, the flight
time, each path limit's verdict and whether the re-propagation meets the terminal conditions."""
from __future__ import annotations

from app.kinds.headlines import Headline, limit_headlines, number, terminal_headline

# What each objective is, in a reader's words (the result's objective.name is the API's name).
OBJECTIVE_WORDS = {"max_crossrange": "crossrange (final latitude)", "max_downrange": "downrange (final longitude)",
                   "max_great_circle_range": "great-circle range", "min_heat_load": "total heat load",
                   "max_crossrange_robust": "robust crossrange (mean - k sigma of the final latitude)"}


def objective_headline(objective: dict) -> Headline:
    key = objective.get("name") or ""
    name = OBJECTIVE_WORDS.get(key, key or "objective")
    return number(name, objective.get("value"), objective.get("unit") or "", digits=5)


def headlines(result: dict, params: dict | None = None) -> list[Headline]:
    out = [objective_headline(result["objective"]), number("flight time", result.get("tf_s"), "s", digits=5)]
    out += limit_headlines(result.get("verification"))
    terminal = terminal_headline(result.get("verification"))
    return out + ([terminal] if terminal else [])
