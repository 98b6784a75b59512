"""Dubins car: the shortest path of bounded curvature, here a U-turn."""
from __future__ import annotations

import math

NAME = "dubins-car-u-turn"

# Unit speed, turning rate |w| <= 1 (radius 1): from the origin heading +x to (0, 2) heading -x.
# The heading must turn by pi at a rate of at most 1, so tf >= pi, and the left half circle about
# (0, 1) reaches the end in exactly pi (Dubins 1957: shortest paths are CSC or CCC; here C alone).
PARAMS = {
    "title": "Dubins car: a U-turn of radius 1 in least time",
    "states": [{"name": "x", "initial": 0.0, "final": 0.0}, {"name": "y", "initial": 0.0, "final": 2.0},
               {"name": "theta", "initial": 0.0, "final": math.pi}],
    "controls": [{"name": "w", "lower": -1.0, "upper": 1.0, "unit": "rad/s"}],
    "time": {"initial": 0.0, "final": None, "final_lower": 1.0, "final_upper": 20.0, "final_guess": 4.0},
    "dynamics": {"x": "cos(theta)", "y": "sin(theta)", "theta": "w"},
    "objective": {"sense": "minimize", "expr": "tf"},
    "transcription": {"method": "multiple_shooting", "intervals": 20, "control": "constant", "substeps": 2},
    "guess": {"states": {"x": [0.0, 0.0], "y": [0.0, 2.0]}, "controls": {"w": [0.8, 0.8]}},
}

PRESET = {
    "description": "Dubins car (Dubins, American Journal of Mathematics 79, 1957): unit speed, turning rate at "
                   "most 1 rad/s (radius 1), from the origin heading east to (0, 2) heading west in least "
                   "time. The heading must turn by pi at a rate of at most 1, and the half circle of radius 1 "
                   "does it: the optimum is pi = 3.14159265 s, the control on its bound throughout. RK4 on "
                   "20 intervals of the half circle is accurate to ~1e-8; tolerance 1e-6 s.",
    "optimum": math.pi, "tolerance": 1e-6, "params": PARAMS}
