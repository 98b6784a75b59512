"""COPS 3.0's hang glider with the thermal updraft given as a table instead of a formula."""
from __future__ import annotations

import math

NAME = "hang-glider-thermal-table"

# The updraft ua(x) = uc (1 - X) exp(-X), X = (x/r0 - 2.5)^2 (uc = 2.5 m/s, r0 = 100 m) sampled
# every 10 m on [0, 1500] m: the same problem, its data read from a table through the B-spline.
_XS = [10.0 * i for i in range(151)]
_UA = [2.5 * (1 - (x / 100.0 - 2.5) ** 2) * math.exp(-((x / 100.0 - 2.5) ** 2)) for x in _XS]

# The hang-glider preset's problem (solvers/ocp/cases.py), restated here rather than imported: the
# preset list imports this package, so importing it back would make a cycle.
PARAMS = {
    "title": "Hang glider through a thermal given as a table (COPS 3.0 problem 11)",
    "constants": {"mass": 100.0, "g": 9.81, "c0": 0.034, "c1": 0.069662, "S": 14.0, "rho": 1.13},
    "tables": {"updraft": {"axes": [_XS], "values": _UA}},
    "states": [{"name": "x", "initial": 0.0, "lower": 0.0, "upper": 1500.0, "scale": 1000.0, "unit": "m"},
               {"name": "y", "initial": 1000.0, "final": 900.0, "scale": 1000.0, "unit": "m"},
               {"name": "vx", "initial": 13.2275675, "final": 13.2275675, "lower": 0.0, "scale": 10.0,
                "unit": "m/s"},
               {"name": "vy", "initial": -1.28750052, "final": -1.28750052, "scale": 1.0, "unit": "m/s"}],
    "controls": [{"name": "CL", "lower": 0.0, "upper": 1.4}],
    "time": {"initial": 0.0, "final": None, "final_lower": 10.0, "final_upper": 200.0, "final_guess": 100.0},
    "expressions": {
        "ua": "updraft(x)",
        "Vy": "vy - ua",
        "vr": "sqrt(vx**2 + Vy**2)",
        "CD": "c0 + c1*CL**2",
        "drag": "0.5*CD*rho*S*vr**2",
        "lift": "0.5*CL*rho*S*vr**2",
    },
    "dynamics": {"x": "vx", "y": "vy",
                 "vx": "(-lift*Vy/vr - drag*vx/vr)/mass",
                 "vy": "(lift*vx/vr - drag*Vy/vr - mass*g)/mass"},
    "objective": {"sense": "maximize", "expr": "final(x)"},
    "transcription": {"method": "multiple_shooting", "intervals": 100, "control": "linear", "substeps": 2},
    "guess": {"states": {"x": [0.0, 1250.0], "vx": [13.2275675, 13.2275675], "vy": [-1.28750052, -1.28750052]},
              "controls": {"CL": [0.7, 0.7]}},
}

PRESET = {
    "description": "Hang glider, maximum range through a thermal updraft, with the updraft as tabulated data: "
                   "COPS 3.0 (Dolan, More & Munson 2004) problem 11 after Bulirsch, Nerz, Pesch & von Stryk "
                   "(1993), its updraft uc (1 - X) exp(-X), X = (x/r0 - 2.5)^2, sampled every 10 m on "
                   "[0, 1500] m into a 1-D table read through the B-spline interpolant. Published final "
                   "range 1248.03 m (the formula). The cubic spline of 10 m samples differs from the "
                   "formula by ~1e-5 m/s; like the hang-glider preset the 100 intervals give 1247.99 m; "
                   "tolerance 0.2 m.",
    "optimum": 1248.03, "tolerance": 0.2, "params": PARAMS}
