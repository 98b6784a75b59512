"""The Betts shuttle's maximum-crossrange reentry written as an ``ocp`` body, which the ``betts-shuttle-ocp``
preset (:mod:`solvers.ocp.cases`) poses as it is and the robust presets (:mod:`solvers.ocp.robust.presets`)
pose with a heating limit and uncertain aerodynamics.

Betts' English units; the numbers are those of the ``reentry`` kind's ``betts-max-crossrange`` preset
(``solvers/models/shuttle.py``, ``reentry.md``): the same vehicle, atmosphere, planet, boundary
conditions, bounds and grid (100 intervals, linear controls, 2 RK4 steps per interval), so that both
kinds must agree.  Standard library only.
"""
from __future__ import annotations

import math
from typing import Any

DEG = math.pi / 180.0

# Betts, Practical Methods for Optimal Control, 2nd ed., sec. 6.3, eqs. 6.93-6.101 (English units).
BETTS_SHUTTLE: dict[str, Any] = {
    "title": "Space Shuttle reentry, maximum crossrange (Betts sec. 6.3)",
    "constants": {
        "mu": 0.14076539e17, "Re": 20902900.0, "S": 2690.0, "mass": 203000.0 / 32.174,
        "rho0": 0.002378, "hr": 23800.0,
        "a0": -0.20704, "a1": 0.029244, "b0": 0.07854, "b1": -0.61592e-2, "b2": 0.621408e-3,
        "c0": 1.0672181, "c1": -0.19213774e-1, "c2": 0.21286289e-3, "c3": -0.10117249e-5,
    },
    "states": [
        {"name": "h", "initial": 260000.0, "final": 80000.0, "lower": 0.0, "upper": 400000.0,
         "scale": 1e5, "unit": "ft"},
        {"name": "lon", "initial": 0.0, "scale": 1.0, "unit": "rad"},
        {"name": "lat", "initial": 0.0, "lower": -89 * DEG, "upper": 89 * DEG, "scale": 1.0, "unit": "rad"},
        {"name": "v", "initial": 25600.0, "final": 2500.0, "lower": 100.0, "upper": 40000.0,
         "scale": 1e4, "unit": "ft/s"},
        {"name": "gamma", "initial": -1 * DEG, "final": -5 * DEG, "lower": -89 * DEG, "upper": 89 * DEG,
         "scale": 1.0, "unit": "rad"},
        {"name": "psi", "initial": 90 * DEG, "scale": 1.0, "unit": "rad"},
    ],
    "controls": [
        {"name": "alpha", "lower": -90 * DEG, "upper": 90 * DEG, "scale": 1.0, "unit": "rad"},
        {"name": "beta", "lower": -90 * DEG, "upper": 1 * DEG, "scale": 1.0, "unit": "rad"},
    ],
    "time": {"initial": 0.0, "final": None, "final_lower": 100.0, "final_upper": 10000.0},
    "expressions": {
        "r": "Re + h",
        "rho": "rho0*exp(-h/hr)",
        "a_deg": "alpha*180/pi",
        "CL": "a0 + a1*a_deg",
        "CD": "b0 + b1*a_deg + b2*a_deg**2",
        "qbar": "0.5*rho*v**2",
        "lift": "qbar*S*CL",
        "drag": "qbar*S*CD",
        "grav": "mu/r**2",
        "heat_rate": "(c0 + c1*a_deg + c2*a_deg**2 + c3*a_deg**3)*17700*sqrt(rho)*(0.0001*v)**3.07",
    },
    "dynamics": {
        "h": "v*sin(gamma)",
        "lon": "v*cos(gamma)*sin(psi)/(r*cos(lat))",
        "lat": "v*cos(gamma)*cos(psi)/r",
        "v": "-drag/mass - grav*sin(gamma)",
        "gamma": "lift*cos(beta)/(mass*v) + cos(gamma)*(v/r - grav/v)",
        "psi": "lift*sin(beta)/(mass*v*cos(gamma)) + v*cos(gamma)*sin(psi)*sin(lat)/(r*cos(lat))",
    },
    "objective": {"sense": "maximize", "expr": "final(lat)*180/pi"},
    "transcription": {"method": "multiple_shooting", "intervals": 100, "control": "linear", "substeps": 2},
    # The reentry kind's straight-line guess (solvers/reentry guess "linear"): tf 2000 s, alpha 17
    # deg, bank -60 deg, longitude to 1.2 rad, latitude to 0.5 rad, heading to 0.
    "guess": {"tf": 2000.0, "states": {"lon": [0.0, 1.2], "lat": [0.0, 0.5], "psi": [90 * DEG, 0.0]},
              "controls": {"alpha": [17 * DEG, 17 * DEG], "beta": [-60 * DEG, -60 * DEG]}},
}
