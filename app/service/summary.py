"""The key numbers of a job's result, as the CLI, the console and trade tables show them.

A kind declares its own (``KindSpec.key_numbers``); for a kind that has not,
the scalar fields of the result's top three levels stand in.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

MAX_GENERIC = 10


class SpecField(Mapping[str, Any]):
    """kind -> one field of its ``KindSpec``, for the kinds whose field is set: a view of the registry,
    read on each use (a kind registered later is in it), never a table of its own."""

    def __init__(self, name: str):
        self.name = name

    def _items(self) -> dict[str, Any]:
        from app.kinds import KINDS

        return {kind: value for kind, spec in KINDS.items() if (value := getattr(spec, self.name, None)) is not None}

    def __getitem__(self, kind: str) -> Any:
        return self._items()[kind]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items())

    def __len__(self) -> int:
        return len(self._items())


# Where each kind takes a warm start from a stored job (KindSpec.warm_start_field): the console's "warm start"
# button and the continuation walk of a study fill it in.
WARM_START_FIELD = SpecField("warm_start_field")
# A key number whose better direction never depends on the parameters (KindSpec.fixed_objective): a study keeps
# the best job of each point by it and, once every point is final, retries a point from a neighbour that did
# better (multimodal problems: a cold start can land in a worse local optimum than its neighbour's).
FIXED_OBJECTIVE = SpecField("fixed_objective")


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
