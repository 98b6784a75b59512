"""What a trade study's plot charts (``GET /v1/studies/{id}/plot.{png,svg}``): the swept value against
the outputs that vary, with units, as an engineer would draw it.

The kind declares its outputs (``KindSpec.trade_outputs``: the objective, its named results, the final
time, each with a label and unit; :mod:`app.kinds.trade`) and, for swept paths whose names carry no unit,
their label (``KindSpec.swept_label``).  Solver counts, booleans and words stay in the trade table; an
output that is the same at every point (a fixed terminal value) is dropped, since a flat line says only
what the problem fixed.  A second sweep gives one curve per value.  :mod:`app.results.study_plot` draws it.
"""
from __future__ import annotations

import math

from app.kinds.trade import TradeOutput, axis_label, name_label, name_unit
from app.results.study_plot import TradeChart, TradeLine, TradePanel
from app.runtime.db import Database
from app.runtime.models import Study
from app.service.studies import sweep_paths, trade_rows

MAX_PANELS = 6
# An output whose spread over the points is within this share of its magnitude is constant: far above
# what an NLP leaves on a fixed value (its constraint tolerance, ~1e-8 of the scaled value) and far below
# any trade read off a plot (a panel's resolution is ~1e-3 of its range).
CONSTANT_RELATIVE = 1e-6
CONSTANT_ABSOLUTE = 1e-9   # ... and a fixed value of 0 (any unit of ours: 1e-9 is below every tolerance)
# Row columns that are bookkeeping, never a result.
BOOKKEEPING = {"index", "status", "job_id", "warm_start_from", "error_code", "jobs"}


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _constant(values: list[float]) -> bool:
    if len(values) < 2:
        return False
    spread = max(values) - min(values)
    return spread <= CONSTANT_RELATIVE * max(abs(v) for v in values) + CONSTANT_ABSOLUTE


def _same(a: list, b: list) -> bool:
    """Two series equal at every point, to the tolerance of a constant (a number copied into two key
    numbers, or a fixed final value that is the swept value)."""
    return len(a) == len(b) and all(
        _number(u) and _number(v) and math.isclose(u, v, rel_tol=CONSTANT_RELATIVE, abs_tol=CONSTANT_ABSOLUTE)
        for u, v in zip(a, b))


def _swept(kind_spec, params: dict, paths: list[str]) -> str:
    """The swept parameter's axis label: each path named by the kind (or by its unit suffix)."""
    named = [kind_spec.swept_label(params, p) if kind_spec is not None and kind_spec.swept_label else
             (name_label(p), name_unit(p)) for p in paths]
    units = {unit for _, unit in named}
    if len(units) == 1:    # several paths set to one value (robust's two k): one unit
        return axis_label(" = ".join(label for label, _ in named), units.pop())
    return " = ".join(axis_label(label, unit) for label, unit in named)


def _generic_outputs(rows: list[dict], columns: list[str]) -> list[TradeOutput]:
    """A kind that declares none: every key number that is a float somewhere (ints are counts)."""
    return [TradeOutput(key, name_label(key), name_unit(key)) for key in columns
            if any(isinstance(r.get(key), float) for r in rows)]


def chart(*, kind_spec, title: str, sweeps: list[dict], rows: list[dict], result: dict | None,
          params: dict) -> TradeChart:
    """The chart of a study's trade table ``rows`` (:func:`app.service.studies.trade_table`); ``result``
    and ``params`` are one succeeded point's (what the kind's declarations read units from; None: no
    point succeeded yet)."""
    paths = sweep_paths(sweeps[0])
    x_key = " & ".join(paths)
    group_key = " & ".join(sweep_paths(sweeps[1])) if len(sweeps) > 1 else None
    columns = [k for k in dict.fromkeys(k for r in rows for k in r)
               if k not in BOOKKEEPING and k != x_key and k != group_key]
    declare = getattr(kind_spec, "trade_outputs", None)
    if result is None:
        outputs: list[TradeOutput] = []
    elif declare is not None:
        outputs = [o for o in declare(result, params) if o.key in columns]
    else:
        outputs = _generic_outputs(rows, columns)
    ok = [r for r in rows if r.get("status") == "succeeded"]
    groups = list(dict.fromkeys(r.get(group_key) for r in ok)) if group_key else [None]
    panels: dict[str, TradePanel] = {}
    constant: list[str] = []
    repeated: list[str] = []
    charted_series: list[list] = []
    for output in outputs:
        values = [r[output.key] for r in ok if _number(r.get(output.key))]
        if not values:
            continue
        if _constant(values):
            constant.append(output.key)
            continue
        series = [r.get(output.key) for r in ok]
        if any(_same(series, seen) for seen in charted_series) or _same(series, [r.get(x_key) for r in ok]):
            repeated.append(output.key)    # the objective again (final latitude), or the swept value itself
            continue
        charted_series.append(series)
        shared = output.panel is not None
        panel = panels.setdefault(output.panel or output.key, TradePanel(
            output.panel or output.key, axis_label(output.panel or output.label, output.unit), []))
        for g in groups:
            pts = [(r[x_key], r[output.key]) for r in ok
                   if (group_key is None or r.get(group_key) == g) and _number(r.get(output.key))]
            names = [output.label] if shared else []
            names += [f"{group_key} = {g}"] if group_key is not None else []
            if pts:
                panel.lines.append(TradeLine(", ".join(names) or None, [x for x, _ in pts],
                                             [float(y) for _, y in pts]))
    charted = {o.key for o in outputs if (o.panel or o.key) in panels} | set(constant) | set(repeated)
    return TradeChart(title=title, x_label=_swept(kind_spec, params, paths),
                      panels=list(panels.values())[:MAX_PANELS],
                      failed_x=[r[x_key] for r in rows if r.get("status") == "failed"],
                      table_only=[c for c in columns if c not in charted], constant=constant,
                      repeated=repeated)


def trade_chart(db: Database, study: Study) -> TradeChart:
    """The chart of a stored study, its units read from its first succeeded point."""
    from app.kinds import KINDS

    rows: list[dict] = []
    first, result = None, None
    for row, stored in trade_rows(db, study):  # the table's own read of the first point's result, kept
        rows.append(row)
        if first is None and row.get("status") == "succeeded" and row.get("job_id"):
            first, result = row, stored
    point = next((p for p in study.points if first and p["index"] == first["index"]), None)
    params = point["params"] if point else study.base_params
    return chart(kind_spec=KINDS.get(study.kind), title=f"study {study.label or study.id[:8]}: "
                 f"{study.kind} trade curve", sweeps=study.sweeps, rows=rows, result=result, params=params)
