"""A vehicle as data: its numbers (NLP parameters), its structure (solver cache key), and JSON.

A built NLP takes the vehicle's numbers as parameters (mass, area, the aero polynomial
coefficients, the aero scales, the Sutton-Graves nose radius and constant), so one compiled solver
serves every vehicle of the same *structure*: the model kinds, the aero table, the atmosphere and
the planet (baked into the graph: see :mod:`solvers.models.aerodynamics` for why tables are).
:func:`model_key` names that structure; :func:`aero_numbers`/:func:`heating_numbers` and
:func:`with_symbols` go from numbers to symbols and back.  :func:`vehicle_to_dict` and
:func:`vehicle_from_dict` carry a whole vehicle (tables, heating, planet, atmosphere) through JSON,
e.g. to a Monte Carlo worker.
"""
from __future__ import annotations

import dataclasses
from typing import Any

from solvers.models.aerodynamics import AeroTable
from solvers.models.atmosphere import Atmosphere
from solvers.models.heating import SuttonGraves
from solvers.models.planet import Planet
from solvers.models.shuttle import Vehicle


def aero_numbers(v: Vehicle) -> list:
    """The CL then CD polynomial coefficients; none for a table (baked into the graph)."""
    if v.aero_table is not None:
        return []
    return [*v.cl_coeffs, *v.cd_coeffs]


def heating_numbers(v: Vehicle) -> list:
    """None for Betts' fit (its coefficients are structure); ``(nose radius, k)`` for Sutton-Graves."""
    if v.heating is None:
        return []
    k = v.planet.sutton_graves_k if v.heating.k is None else v.heating.k
    return [v.heating.nose_radius_m, k]


def with_symbols(v: Vehicle, aero, heating) -> dict:
    """``dataclasses.replace`` overrides putting symbols ``aero`` (as :func:`aero_numbers`) and
    ``heating`` (as :func:`heating_numbers`) in place of the vehicle's numbers."""
    over: dict[str, Any] = {}
    if v.aero_table is None:
        ncl = len(v.cl_coeffs)
        over["cl_coeffs"] = tuple(aero[k] for k in range(ncl))
        over["cd_coeffs"] = tuple(aero[ncl + k] for k in range(len(v.cd_coeffs)))
    if v.heating is not None:
        over["heating"] = dataclasses.replace(v.heating, nose_radius_m=heating[0], k=heating[1])
    return over


def model_key(v: Vehicle) -> tuple:
    """Every structural choice of a vehicle's model (kinds, the baked-in aero table, atmosphere
    and planet, rotation), none of its NLP parameters."""
    aero = (("table", v.aero_table) if v.aero_table is not None
            else ("polynomial", len(v.cl_coeffs), len(v.cd_coeffs)))
    heating = ("sutton_graves",) if v.heating is not None else ("betts", tuple(v.heat_coeffs))
    return aero, heating, v.atmosphere, v.planet, v.rotating_earth


def vehicle_to_dict(v: Vehicle) -> dict:
    """Plain JSON types; :func:`vehicle_from_dict` inverts it."""
    d = dataclasses.asdict(v)
    out = {k: (list(val) if isinstance(val, tuple) else val) for k, val in d.items()}
    if v.aero_table is not None:
        t = v.aero_table
        out["aero_table"] = {"alpha_deg": list(t.alpha_deg), "mach": list(t.mach),
                             "cl": [list(r) for r in t.cl], "cd": [list(r) for r in t.cd]}
    out["atmosphere"] = {k: (list(val) if isinstance(val, tuple) else val) for k, val in d["atmosphere"].items()}
    return out


def vehicle_from_dict(d: dict) -> Vehicle:
    d = dict(d)
    d["cl_coeffs"], d["cd_coeffs"], d["heat_coeffs"] = (tuple(d[k]) for k in ("cl_coeffs", "cd_coeffs",
                                                                             "heat_coeffs"))
    d["atmosphere"] = Atmosphere(**d["atmosphere"])
    d["planet"] = Planet(**d["planet"])
    d["aero_table"] = AeroTable(**d["aero_table"]) if d.get("aero_table") else None
    d["heating"] = SuttonGraves(**d["heating"]) if d.get("heating") else None
    return Vehicle(**d)
