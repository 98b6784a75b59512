"""Time-optimal double integrator: bang-bang control with one switch."""
from __future__ import annotations

NAME = "double-integrator-min-time"

# x' = v, v' = u, |u| <= 1, from x = 1 at rest to the origin at rest in least time.  Pontryagin's
# minimum principle gives u = -1 then +1 with one switch at the half time; x(t) = 1 - t^2/2 reaches
# 1/2 at t = 1 with v = -1, and the mirror arc brings it to rest at x = 0: tf = 2 sqrt(x0 / umax) = 2.
PARAMS = {
    "title": "Double integrator, minimum time from x = 1 to the origin at rest, |u| <= 1",
    "states": [{"name": "x", "initial": 1.0, "final": 0.0}, {"name": "v", "initial": 0.0, "final": 0.0}],
    "controls": [{"name": "u", "lower": -1.0, "upper": 1.0}],
    "time": {"initial": 0.0, "final": None, "final_lower": 0.5, "final_upper": 10.0, "final_guess": 2.5},
    "dynamics": {"x": "v", "v": "u"},
    "objective": {"sense": "minimize", "expr": "tf"},
    "transcription": {"method": "multiple_shooting", "intervals": 20, "control": "constant", "substeps": 2},
    "guess": {"states": {"v": [-0.5, -0.5]}, "controls": {"u": [-0.5, 0.5]}},
}

PRESET = {
    "description": "Time-optimal double integrator (bang-bang): x' = v, v' = u, |u| <= 1, from x = 1 at rest "
                   "to the origin at rest. The minimum principle (Pontryagin et al. 1962; Bryson & Ho, "
                   "Applied Optimal Control, 1975) gives full braking then full thrust with one switch at "
                   "half time: tf = 2 sqrt(x0/umax), the closed-form optimum 2.0 s. 20 intervals of "
                   "piecewise-constant control put the switch (tf/2) on a node, where the piecewise-"
                   "constant control is exact and RK4 integrates the quadratic arcs exactly; tolerance "
                   "1e-6 s (the NLP's convergence, not the grid).",
    "optimum": 2.0, "tolerance": 1e-6, "params": PARAMS}
