"""Each time series or front of a result as a CSV table with unit-bearing column headers.

A kind declares its tables (``KindSpec.tables``: name -> picker), most of them :func:`columns_at` a
block of its result; the registry (:mod:`app.kinds`) hands them over here with :func:`register_tables`,
as it does the plots, since this machinery sits below the kinds and never imports them.
"""
from __future__ import annotations

import csv
import io
from typing import Any, Callable

Picker = Callable[[dict], "dict[str, list] | None"]
_SOURCES: dict[str, dict[str, Picker]] = {}


def columns(block: dict | None) -> dict[str, list] | None:
    """The equal-length list columns of a result block (``t_s``, ``altitude_m``, ...)."""
    if not isinstance(block, dict):
        return None
    cols = {k: v for k, v in block.items() if isinstance(v, list) and v and not isinstance(v[0], (list, dict))}
    lengths = {len(v) for v in cols.values()}
    return cols if cols and len(lengths) == 1 else None


def columns_at(path: str) -> Picker:
    """The picker of the block at a dotted ``path`` of the result (``"verification.trajectory"``)."""
    def pick(r: Any):
        for part in path.split("."):
            r = r.get(part) if isinstance(r, dict) else None
        return columns(r)
    return pick


def register_tables(kind: str, tables: dict[str, Picker]) -> None:
    """Make ``tables`` the CSV tables of ``kind`` (called by the registry, :mod:`app.kinds`)."""
    _SOURCES[kind] = dict(tables)


def tables_for(kind: str, result: dict) -> dict[str, dict[str, list]]:
    out = {}
    for name, pick in _SOURCES.get(kind, {}).items():
        cols = pick(result)
        if cols:
            out[name] = cols
    return out


def to_csv(cols: dict[str, list]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    # repr keeps every digit of a float (17 significant), so the CSV round-trips to the JSON's numbers
    w.writerows([["" if v is None else repr(v) if isinstance(v, float) else v for v in row]
                 for row in zip(*cols.values())])
    return buf.getvalue()
