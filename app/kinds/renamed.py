"""Parameters under an old name, still accepted: each is moved to its one name before validation.

A kind keeps the old field in its model only for the OpenAPI document (``Field(deprecated=...)`` marks it
``deprecated``, ``exclude=True`` keeps it out of every dump), and calls :func:`move_renamed` from a
``model_validator(mode="before")``: stored parameters, a job's ``GET .../params`` and everything the
kind reads then carry the new name only.  The warm start is the first such rename: one spelling,
``initial_guess.from_job``, in every kind (/work/notes/decisions.md, issue 34 item 5).
"""
from __future__ import annotations

from typing import Any


def _parent(data: dict, path: tuple[str, ...], *, create: bool) -> dict | None:
    node = data
    for part in path[:-1]:
        child = node.get(part)
        if not isinstance(child, dict):
            if not create or child is not None:
                return None
            child = {}
        node[part] = child = dict(child)  # a copy: the caller's input is never changed
        node = child
    return node


def _under(old: Any, new: Any) -> Any:
    """``new`` over ``old``: groups merge key by key, anything else given under the new name wins."""
    if isinstance(old, dict) and isinstance(new, dict):
        return {**old, **{k: _under(old.get(k), v) for k, v in new.items()}}
    return old if new is None else new


def move_renamed(data: Any, old: tuple[str, ...], new: tuple[str, ...]) -> Any:
    """``data`` (a kind's raw parameters) with the value at ``old`` moved to ``new``; a null at ``old`` is
    dropped.  Where both are given (a preset written with the old name, overrides with the new one)
    they merge, the new name winning."""
    if not isinstance(data, dict):
        return data
    data = dict(data)
    source = _parent(data, old, create=False)
    if source is None or old[-1] not in source:
        return data
    value = source.pop(old[-1])
    if value is None:
        return data
    target = _parent(data, new, create=True)
    if target is None:
        return data  # the new group is not an object: the model's own error names it
    target[new[-1]] = _under(value, target.get(new[-1]))
    return data
