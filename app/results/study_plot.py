"""A trade study's chart: the panels an engineer draws (each varying output against the swept value) and
their drawing.  :mod:`app.service.study_chart` decides what goes in (:class:`TradeChart`, from the kind's
declarations); this module only draws it, with matplotlib's object API (``Figure``, no pyplot state).

Axes show plain numbers (no ``1e6`` offset or multiplier in a corner: a reader copies tick values off the
axis as they stand), and every axis label carries its unit.
"""
from __future__ import annotations

import io
from dataclasses import dataclass, field

from matplotlib.figure import Figure


@dataclass(frozen=True)
class TradeLine:
    """One curve of a panel: the succeeded points of one value of the second sweep (``name``; None: a
    study with one sweep), in sweep order."""

    name: str | None
    x: list
    y: list[float]


@dataclass(frozen=True)
class TradePanel:
    """One output against the swept value: ``key`` its trade-table column, ``label`` its axis (with unit)."""

    key: str
    label: str
    lines: list[TradeLine]


@dataclass(frozen=True)
class TradeChart:
    """What a study's plot shows: ``x_label`` the swept parameter (with unit), the panels in order, the
    swept values of failed points (marked on each panel's axis), and why the other key numbers are not
    charted (``table_only``: counts, booleans and words; ``constant``: the same at every point;
    ``repeated``: another panel's series again, or the swept value itself)."""

    title: str
    x_label: str
    panels: list[TradePanel]
    failed_x: list = field(default_factory=list)
    table_only: list[str] = field(default_factory=list)
    constant: list[str] = field(default_factory=list)
    repeated: list[str] = field(default_factory=list)


def _plain(ax) -> None:
    """Plain tick labels on both numeric axes (matplotlib's default moves a shared offset or a power of
    ten into the corner, where nobody reads it)."""
    for axis in ("x", "y"):
        try:
            ax.ticklabel_format(axis=axis, style="plain", useOffset=False)
        except AttributeError:
            pass   # a categorical axis (swept words): its labels are the words


def draw(chart: TradeChart) -> Figure:
    """The chart as a figure: one panel per output, sharing the swept axis."""
    n = max(1, len(chart.panels))
    fig = Figure(figsize=(8, 2.6 * n + 0.6), dpi=100)
    axes = fig.subplots(n, 1, squeeze=False, sharex=True)[:, 0]
    for ax, panel in zip(axes, chart.panels):
        for line in panel.lines:
            ax.plot(line.x, line.y, "o-", ms=4, label=line.name)
        if chart.failed_x:
            ax.plot(chart.failed_x, [ax.get_ylim()[0]] * len(chart.failed_x), "rx", ms=8,
                    label="failed (e.g. infeasible)")
        if chart.failed_x or any(line.name for line in panel.lines):
            ax.legend(loc="best", fontsize=8)
        ax.set_ylabel(panel.label)
        ax.grid(True, alpha=0.3)
        _plain(ax)
    if not chart.panels:
        axes[0].text(0.5, 0.5, "no output varies yet" if chart.constant else "no numbers yet",
                     ha="center", va="center", transform=axes[0].transAxes)
    axes[-1].set_xlabel(chart.x_label)
    fig.suptitle(chart.title)
    fig.tight_layout()
    return fig


def render(chart: TradeChart, fmt: str) -> bytes:
    """The chart as PNG or SVG bytes."""
    buf = io.BytesIO()
    draw(chart).savefig(buf, format=fmt)
    return buf.getvalue()
