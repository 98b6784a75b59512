"""The key numbers of a job's result, as the CLI, the console and trade tables show them.

A kind declares its own (``KindSpec.key_numbers``); for a kind that has not,
the scalar fields of the result's top three levels stand in.
"""
from __future__ import annotations

from typing import Any

MAX_GENERIC = 10

# Where each kind takes a warm start from a stored job: the console's "warm start" button and the
# continuation walk of a study fill it in.  midcourse has none (NSGA-II starts from its seed).
# A key number whose better direction never depends on the parameters: a study keeps the best job of each
# point by it and, once every point is final, retries a point from a neighbour that did better (multimodal
# problems: a cold start can land in a worse local optimum than its neighbour's).
FIXED_OBJECTIVE = {"intercept": ("finite_thrust.fuel_kg", "min")}

WARM_START_FIELD = {"reentry": "initial_guess.from_job", "robust_reentry": "initial_guess.from_job",
                    "intercept": "finite_thrust.from_job", "ocp": "guess.from_job"}


def _generic(result: dict, prefix: str = "", depth: int = 0, out: dict | None = None) -> dict[str, Any]:
    """Scalars breadth-first: the top level's first, then one and two levels down."""
    out = {} if out is None else out
    for key, value in result.items():
        if len(out) >= MAX_GENERIC:
            return out
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            out[f"{prefix}{key}"] = value
    for key, value in result.items():
        if isinstance(value, dict) and depth < 2:
            _generic(value, f"{prefix}{key}.", depth + 1, out)
    return out


def key_numbers(kind: str, result: dict | None) -> dict[str, Any]:
    if not result:
        return {}
    from app.kinds import KINDS

    pick = getattr(KINDS.get(kind), "key_numbers", None)
    if pick is not None:
        try:
            return dict(pick(result))
        except (KeyError, TypeError, ValueError):
            pass  # an older stored result without the fields the kind picks now
    return _generic(result)


def headlines(kind: str, result: dict | None, params: dict | None = None) -> list[dict]:
    """The kind's headline numbers (app.kinds.headlines) as dicts; a kind that declares none, or a stored
    result older than the fields it reads, gets its key numbers as plain lines."""
    if not result:
        return []
    from app.kinds import KINDS
    from app.kinds.headlines import number

    declare = getattr(KINDS.get(kind), "headlines", None)
    if declare is not None:
        try:
            return [h.as_dict() for h in declare(result, params)]
        except (KeyError, TypeError, ValueError, AttributeError):
            pass  # an older stored result without the fields the kind reads now
    return [number(name, value).as_dict() for name, value in key_numbers(kind, result).items()
            if isinstance(value, (int, float)) and not isinstance(value, bool)]
