"""The plotting machinery every kind shares: :class:`PlotDef`, the helpers a kind's plots use
(:func:`floats`, :func:`pick`, :func:`has`), :func:`plots_for` and :func:`render`, drawn with
matplotlib's object API (``Figure``: thread-safe, no pyplot state, no display).  Axis labels carry
the API's units; the title names the job.

Each kind's plots live in its own package (``app/kinds/<kind>/plots.py``) and reach this module
through ``KindSpec.plots``: the registry (:mod:`app.kinds`) hands them over with
:func:`register_plots` when it loads, so this module never imports a kind (kinds sit above it).
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class PlotDef:
    name: str
    title: str
    draw: Callable[..., None]          # draw(fig, result, params)
    available: Callable[[dict], bool]  # does this result hold what the plot needs?
    size: tuple[float, float] = (8, 5)  # inches


def floats(values) -> np.ndarray:
    """A JSON list of numbers as floats, null as NaN."""
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def pick(d: dict, path: str):
    """``d``'s value at a dotted ``path``, None where any part is missing or null."""
    for part in path.split("."):
        if not isinstance(d, dict) or d.get(part) is None:
            return None
        d = d[part]
    return d


def has(*paths: str) -> Callable[[dict], bool]:
    """A PlotDef's ``available``: the result holds every one of ``paths``."""
    return lambda r: all(pick(r, p) is not None for p in paths)


def draw_band(ax, t, mean, std, k: float, *, scale: float = 1.0, color: str = "C0") -> None:
    """A Monte Carlo's mean and its ``mean +- k std`` envelope against ``t`` (the robust kinds' plots)."""
    mean, std = floats(mean) * scale, floats(std) * scale
    ax.fill_between(floats(t), mean - k * std, mean + k * std, color=color, alpha=0.3,
                    label=f"mean +- {k:g} sigma")
    ax.plot(floats(t), mean, color=color, lw=1.5, label="mean")


def draw_histogram(ax, values, *, marks: list[tuple[float | None, str, str]], xlabel: str) -> None:
    """A histogram of per-sample ``values`` (nulls dropped) with vertical ``marks`` ``(x, label, line
    style)``; a mark at None is left out."""
    v = floats(values)
    v = v[np.isfinite(v)]
    ax.hist(v, bins=max(10, min(60, int(np.sqrt(v.size)))) if v.size else 10, color="C0", alpha=0.7,
            label=f"{v.size} samples")
    for i, (x, label, style) in enumerate(marks):
        if x is not None:
            ax.axvline(x, color=f"C{(i + 1) % 10}", ls=style, lw=1.5, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("samples")
    ax.legend(fontsize=8)


_SOURCES: dict[str, Callable[[dict], list[PlotDef]]] = {}


def register_plots(kind: str, plots: Callable[[dict], list[PlotDef]]) -> None:
    """Make ``plots(result)`` the plot list of ``kind`` (called by the registry, :mod:`app.kinds`)."""
    _SOURCES[kind] = plots


def plots_for(kind: str, result: dict) -> list[PlotDef]:
    """The plots of ``kind`` that ``result`` holds the data for."""
    source = _SOURCES.get(kind)
    return [p for p in (source(result) if source is not None else []) if p.available(result)]


def render(plot: PlotDef, *, result: dict, params: dict, title: str, fmt: str, dpi: int = 100) -> bytes:
    """One plot as PNG or SVG bytes."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=plot.size, dpi=dpi, layout="constrained")
    plot.draw(fig, result, params)
    for ax in fig.axes:
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"{plot.title}: {title}")
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, metadata={"Date": None} if fmt == "svg" else None)
    return buf.getvalue()
