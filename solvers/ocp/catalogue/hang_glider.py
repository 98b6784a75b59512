"""COPS 3.0's hang glider (problem 11): the problem itself, which the ``hang-glider`` preset
(:mod:`solvers.ocp.cases`) poses as it is and ``hang-glider-thermal-table`` poses with its updraft as a table."""
from __future__ import annotations

from typing import Any


# COPS 3.0 problem 11 "Hang glider" (after Bulirsch, Nerz, Pesch, von Stryk 1993).
HANG_GLIDER: dict[str, Any] = {
    "title": "Hang glider: maximum range through a thermal (COPS 3.0 problem 11)",
    "constants": {"uc": 2.5, "r0": 100.0, "um": 2.5, "mass": 100.0, "g": 9.81, "c0": 0.034,
                  "c1": 0.069662, "S": 14.0, "rho": 1.13},
    "states": [{"name": "x", "initial": 0.0, "lower": 0.0, "scale": 1000.0, "unit": "m"},
               {"name": "y", "initial": 1000.0, "final": 900.0, "scale": 1000.0, "unit": "m"},
               {"name": "vx", "initial": 13.2275675, "final": 13.2275675, "lower": 0.0, "scale": 10.0,
                "unit": "m/s"},
               {"name": "vy", "initial": -1.28750052, "final": -1.28750052, "scale": 1.0, "unit": "m/s"}],
    "controls": [{"name": "CL", "lower": 0.0, "upper": 1.4}],
    "time": {"initial": 0.0, "final": None, "final_lower": 10.0, "final_upper": 200.0, "final_guess": 100.0},
    "expressions": {
        "X": "(x/r0 - 2.5)**2",
        "ua": "uc*(1 - X)*exp(-X)",
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
