"""Headline numbers: the few lines that say what a job's answer means, declared once per kind.

A kind's ``KindSpec.headlines(result, params)`` returns a list of :class:`Headline` (name, value, unit,
verdict); the CLI (``trajlab wait``/``result``), the console's key numbers, the job list and the HTML
report all print them through :func:`app.service.summary.headlines`, so "crossrange 30.62 deg" or
"heating limit held: peak 100.02% of 794,955 W/m^2" reads the same everywhere.  The helpers below are
the shared pieces: a plain number, and a limit checked on a dense re-propagation (the reentry family's
``verification.limits``).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

# Verdicts a reader can scan for: "held"/"kept" are good news, "not held"/"not kept" are not.
GOOD, BAD = "good", "bad"


@dataclass(frozen=True)
class Headline:
    """One line of an answer: ``name`` and ``value`` in ``unit``; ``verdict`` (e.g. "held", "not held")
    with ``good`` saying whether it is good news (None: no verdict); ``text`` the whole line as a reader
    reads it (what the CLI prints and the console shows)."""

    name: str
    value: float | int | str | None
    unit: str = ""
    verdict: str | None = None
    good: bool | None = None
    text: str = ""

    def as_dict(self) -> dict:
        return asdict(self)


def fmt(value, digits: int = 4) -> str:
    """A number for reading: ``digits`` significant figures, thousands separated; ints as they are."""
    if value is None:
        return "n/a"
    if isinstance(value, bool) or isinstance(value, str):
        return str(value)
    if isinstance(value, int):
        return f"{value:,}"
    if not math.isfinite(value):
        return str(value)
    if abs(value) >= 10 ** digits and abs(value) < 1e9:
        return f"{round(value):,}"
    return format(value, f",.{digits}g")


def number(name: str, value, unit: str = "", *, digits: int = 4) -> Headline:
    """A plain number: ``crossrange 30.62 deg``."""
    text = f"{name} {fmt(value, digits)}" + (f" {unit}" if unit and value is not None else "")
    return Headline(name=name, value=value, unit=unit, text=text)


def verdict(name: str, *, held: bool, value, unit: str, detail: str, words=("held", "not held")) -> Headline:
    """A yes/no answer with the number behind it: ``heating limit held: peak 100.02% of 794,955 W/m^2``."""
    word = words[0] if held else words[1]
    return Headline(name=name, value=value, unit=unit, verdict=word, good=held, text=f"{name} {word}: {detail}")


# The reentry family's path limits (verification.limits): label and unit of each quantity.
LIMIT_LABELS = {"heat_rate_w_m2": ("heating limit", "W/m^2"), "dynamic_pressure_pa": ("dynamic pressure limit", "Pa"),
                "load_factor": ("load factor limit", "g")}


def limit_headlines(verification: dict | None) -> list[Headline]:
    """One verdict per path limit checked on the dense re-propagation: the worst value in percent of the
    limit, and where it happened."""
    out = []
    for key, check in ((verification or {}).get("limits") or {}).items():
        if not isinstance(check, dict) or check.get("limit") in (None, 0) or check.get("max") is None:
            continue
        label, unit = LIMIT_LABELS.get(key, (f"{key} limit", ""))
        share = 100.0 * check["max"] / check["limit"]
        at = f" at t = {check['max_t_s']:.0f} s" if check.get("max_t_s") is not None else ""
        out.append(verdict(label, held=bool(check.get("held")), value=round(share, 4), unit="% of limit",
                           detail=f"peak {share:.2f}% of {fmt(check['limit'], 6)} {unit}{at}"))
    return out


def terminal_headline(verification: dict | None) -> Headline | None:
    """Whether the re-propagated controls meet every requested final value (verification.terminal_held)."""
    v = verification or {}
    if not isinstance(v.get("terminal_held"), bool):
        return None
    misses = [(name, c) for name, c in (v.get("terminal") or {}).items() if isinstance(c, dict)]
    worst = max(misses, key=lambda nc: abs(nc[1].get("miss") or 0) / (nc[1].get("tolerance") or 1), default=None)
    detail = (f"worst {worst[0]} missed by {fmt(abs(worst[1].get('miss') or 0), 3)} "
              f"(tolerance {fmt(worst[1].get('tolerance'), 3)})") if worst else "re-propagated"
    return verdict("terminal conditions", held=v["terminal_held"], value=None, unit="", detail=detail)
