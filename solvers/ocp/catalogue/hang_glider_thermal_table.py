"""COPS 3.0's hang glider with the thermal updraft given as a table instead of a formula."""
from __future__ import annotations

import copy
import math
from typing import Any

from solvers.ocp.catalogue.hang_glider import HANG_GLIDER

NAME = "hang-glider-thermal-table"

# The updraft ua(x) = uc (1 - X) exp(-X), X = (x/r0 - 2.5)^2 (uc = 2.5 m/s, r0 = 100 m) sampled
# every 10 m on [0, 1500] m: the same problem, its data read from a table through the B-spline.
_XS = [10.0 * i for i in range(151)]
_UA = [2.5 * (1 - (x / 100.0 - 2.5) ** 2) * math.exp(-((x / 100.0 - 2.5) ** 2)) for x in _XS]

# The hang-glider problem (solvers/ocp/catalogue/hang_glider.py) with the formula's constants and its
# X and ua expressions replaced by the table, and x kept within the table's axis.
PARAMS: dict[str, Any] = copy.deepcopy(HANG_GLIDER)
PARAMS["title"] = "Hang glider through a thermal given as a table (COPS 3.0 problem 11)"
PARAMS["constants"] = {k: v for k, v in PARAMS["constants"].items() if k not in ("uc", "r0", "um")}
PARAMS["tables"] = {"updraft": {"axes": [_XS], "values": _UA}}
PARAMS["states"][0]["upper"] = _XS[-1]
PARAMS["expressions"] = {"ua": "updraft(x)",
                         **{k: v for k, v in PARAMS["expressions"].items() if k not in ("X", "ua")}}

PRESET = {
    "description": "Hang glider, maximum range through a thermal updraft, with the updraft as tabulated data: "
                   "COPS 3.0 (Dolan, More & Munson 2004) problem 11 after Bulirsch, Nerz, Pesch & von Stryk "
                   "(1993), its updraft uc (1 - X) exp(-X), X = (x/r0 - 2.5)^2, sampled every 10 m on "
                   "[0, 1500] m into a 1-D table read through the B-spline interpolant. Published final "
                   "range 1248.03 m (the formula). The cubic spline of 10 m samples differs from the "
                   "formula by ~1e-5 m/s; like the hang-glider preset the 100 intervals give 1247.99 m; "
                   "tolerance 0.2 m.",
    "optimum": 1248.03, "tolerance": 0.2, "params": PARAMS}
