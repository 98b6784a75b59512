"""The default ``GET /result`` body: the stored result with its bulkiest arrays thinned.

The stored result keeps everything; ``?include=scan`` / ``?include=samples`` ask for the full
arrays.  Each kind says what it thins (``KindSpec.compact``; the registry hands it over with
:func:`register_compaction`, this machinery never imports a kind): a long curve goes through
:func:`thin_curve`, which keeps every local minimum and maximum plus a uniform subsample, so the
curve keeps its shape and every minimum.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

SCAN_POINTS = 300  # with the extrema and the finite-thrust block the intercept preset stays under 50 kB
_SOURCES: dict[str, Callable[[dict, set[str]], dict] | None] = {}


def thin_curve(x: list, y: list, points: int = SCAN_POINTS) -> tuple[list, list]:
    """Every local extremum of y plus ``points`` evenly spaced samples, in order."""
    yv = np.array([np.nan if v is None else v for v in y], dtype=float)
    n = yv.size
    if n <= points:
        return list(x), list(y)
    keep = set(np.linspace(0, n - 1, points).round().astype(int).tolist())
    finite = np.isfinite(yv)
    inner = np.arange(1, n - 1)
    left, mid, right = yv[inner - 1], yv[inner], yv[inner + 1]
    with np.errstate(invalid="ignore"):
        extremum = ((mid <= left) & (mid <= right)) | ((mid >= left) & (mid >= right))
    # an edge of a NaN gap (no transfer) is kept too, so gaps stay visible
    edge = finite[inner] & (~finite[inner - 1] | ~finite[inner + 1])
    keep.update(inner[(extremum & finite[inner]) | edge].tolist())
    idx = sorted(keep)
    return [x[i] for i in idx], [y[i] for i in idx]


def register_compaction(kind: str, compact_body: Callable[[dict, set[str]], dict] | None) -> None:
    """Make ``compact_body`` the default body of ``kind`` (called by the registry, :mod:`app.kinds`)."""
    _SOURCES[kind] = compact_body


def compact(kind: str, result: dict, include: set[str]) -> dict:
    """The default body of a ``kind`` result: what its ``KindSpec.compact`` keeps unless ``include`` asks
    for the full arrays; the stored result itself for a kind that thins nothing."""
    thin = _SOURCES.get(kind)
    return result if thin is None else thin(result, include)
