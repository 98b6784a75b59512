"""Dido's isoperimetric problem: the closed curve of given length that encloses the largest area."""
from __future__ import annotations

import math

NAME = "isoperimetric-dido"

# The curve is parametrised by arc length s in [0, 1] (the "time"): x' = cos(theta), y' = sin(theta),
# theta' = k (the curvature, the control).  It starts and ends at the origin, heading along +x at
# the start (which fixes the circle's rotation about the origin, else the optimum is not isolated).
# The enclosed area is the integral of (x y' - y x') / 2 = (x sin(theta) - y cos(theta)) / 2.
PARAMS = {
    "title": "Dido's problem: the closed curve of length 1 enclosing the largest area",
    "states": [{"name": "x", "initial": 0.0, "final": 0.0, "scale": 0.2},
               {"name": "y", "initial": 0.0, "final": 0.0, "scale": 0.2},
               {"name": "theta", "initial": 0.0}],
    "controls": [{"name": "k", "lower": -50.0, "upper": 50.0, "scale": 6.0}],
    "time": {"initial": 0.0, "final": 1.0},
    "dynamics": {"x": "cos(theta)", "y": "sin(theta)", "theta": "k"},
    "objective": {"sense": "maximize", "integrand": "0.5*(x*sin(theta) - y*cos(theta))"},
    "transcription": {"method": "multiple_shooting", "intervals": 40, "control": "linear", "substeps": 2},
    "guess": {"states": {"theta": [0.0, 6.0]}, "controls": {"k": [6.0, 6.0]}},
}

PRESET = {
    "description": "Dido's isoperimetric problem, the oldest problem of the calculus of variations (see Bryson & "
                   "Ho, Applied Optimal Control, 1975, ch. 3 on isoperimetric constraints): among closed "
                   "curves of length L the circle encloses the most area, L^2/(4 pi). Posed with arc length "
                   "as time, L = 1, heading and curvature as state and control: the optimum "
                   f"1/(4 pi) = {1 / (4 * math.pi)!r}, constant curvature 2 pi. The circle is smooth and RK4 "
                   "on 40 intervals resolves it to ~1e-9; tolerance 1e-7.",
    "optimum": 1 / (4 * math.pi), "tolerance": 1e-7, "params": PARAMS}
