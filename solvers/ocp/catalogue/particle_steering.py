"""Linear tangent steering of a particle: COPS 3.0's particle steering problem."""
from __future__ import annotations

import math

NAME = "particle-steering"

# COPS: x'' = a cos(u), y'' = a sin(u), a = 100, |u| <= pi/2, from rest at the origin to y = 5 with
# x' = 45 and y' = 0 in least time; x(tf) free.  Bryson & Ho (1975) pp. 59-62 (linear tangent law).
PARAMS = {
    "title": "Particle steering: least time to y = 5 with velocity (45, 0) under a thrust of 100 (COPS 3.0)",
    "constants": {"a": 100.0},
    "states": [{"name": "x", "initial": 0.0, "scale": 10.0}, {"name": "y", "initial": 0.0, "final": 5.0},
               {"name": "vx", "initial": 0.0, "final": 45.0, "scale": 45.0},
               {"name": "vy", "initial": 0.0, "final": 0.0, "scale": 10.0}],
    "controls": [{"name": "u", "lower": -math.pi / 2, "upper": math.pi / 2}],
    "time": {"initial": 0.0, "final": None, "final_lower": 0.1, "final_upper": 2.0, "final_guess": 0.6},
    "dynamics": {"x": "vx", "y": "vy", "vx": "a*cos(u)", "vy": "a*sin(u)"},
    "objective": {"sense": "minimize", "expr": "tf"},
    "transcription": {"method": "multiple_shooting", "intervals": 40, "control": "linear", "substeps": 2},
    "guess": {"states": {"x": [0.0, 12.0], "vx": [0.0, 45.0], "vy": [0.0, 0.0]},
              "controls": {"u": [1.0, -1.0]}},
}

PRESET = {
    "description": "Particle steering (linear tangent steering): COPS 3.0 (Dolan, More & Munson, ANL/MCS-TM-273, "
                   "2004) sec. 9, after Bryson & Ho (1975) pp. 59-62 and Betts et al. (1993): x'' = 100 cos u, "
                   "y'' = 100 sin u, |u| <= pi/2, from rest to y = 5, x' = 45, y' = 0 in least time. COPS 3.0 "
                   "Table 9.2: 0.554572 at 400 trapezoidal intervals (0.554577 at 200; the values converge "
                   "from above). The optimal tan u is linear in time, so the angle is smooth: 40 intervals of "
                   "linear control with 2 RK4 steps resolve it to ~1e-6; tolerance 5e-6, the COPS "
                   "value's own 6 digits.",
    "optimum": 0.554572, "tolerance": 5e-6, "params": PARAMS}
