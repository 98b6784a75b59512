"""What a trade study of a kind charts: the outputs that vary with a swept parameter, with their units.

A kind declares ``KindSpec.trade_outputs(result, params) -> [TradeOutput]``: the key numbers (its
``key_numbers`` names, the trade table's columns) an engineer draws against the swept value, each with
the label and unit its axis carries (the objective, the kind's named results, the final time).  Key
numbers it leaves out (solver counts, booleans, words such as the sense) stay in the table only.
``KindSpec.swept_label(params, path) -> (label, unit)`` names a swept parameter when its dotted path
does not carry its unit in its name (an ``ocp`` state's final value); otherwise :func:`name_unit` reads
the unit off the API's unit suffix (``max_heat_rate_w_m2`` -> W/m^2, ``tf_bounds_s.1`` -> s).

:mod:`app.service.study_chart` asks these; :mod:`app.results.study_plot` draws the panels.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TradeOutput:
    """One charted output: ``key`` the key number's name (a trade-table column), ``label`` the words on
    its axis, ``unit`` its unit ("" for a dimensionless number).  Outputs naming the same ``panel`` (its
    axis words; same unit) share one panel, one curve each labelled by ``label``: a Monte Carlo figure
    beside the prediction it checks."""

    key: str
    label: str
    unit: str = ""
    panel: str | None = None


# The API's unit suffixes (docs/architecture.md "Kind packages": units in names), longest match first.
SUFFIX_UNITS = (("_w_m2", "W/m^2"), ("_j_m2", "J/m^2"), ("_mps2", "m/s^2"), ("_mps", "m/s"), ("_deg", "deg"),
                ("_rad", "rad"), ("_km", "km"), ("_kg", "kg"), ("_pa", "Pa"), ("_s", "s"), ("_m", "m"),
                ("_n", "N"))


def name_unit(path: str) -> str:
    """The unit a dotted parameter or result name carries in its last named part ("" for none):
    ``path.max_heat_rate_w_m2`` -> ``W/m^2``, ``tf_bounds_s.1`` -> ``s`` (list indices skipped)."""
    parts = [p for p in path.split(".") if p and not p.isdigit()]
    last = parts[-1].lower() if parts else ""
    return next((unit for suffix, unit in SUFFIX_UNITS if last.endswith(suffix)), "")


def name_label(path: str) -> str:
    """A dotted name without the unit suffix :func:`name_unit` reads: ``path.max_heat_rate_w_m2`` ->
    ``path.max_heat_rate``, ``tf_bounds_s.1`` -> ``tf_bounds.1``."""
    parts = path.split(".")
    for i in range(len(parts) - 1, -1, -1):
        if parts[i] and not parts[i].isdigit():
            suffix = next((sfx for sfx, _ in SUFFIX_UNITS if parts[i].lower().endswith(sfx)), "")
            if suffix and len(parts[i]) > len(suffix):
                parts[i] = parts[i][:-len(suffix)]
            break
    return ".".join(parts)


def axis_label(label: str, unit: str) -> str:
    """``label [unit]``, or the label alone for a dimensionless quantity."""
    return f"{label} [{unit}]" if unit else label
