"""Kelly's block move: the minimum-force rest-to-rest transfer of a point mass."""
from __future__ import annotations

NAME = "kelly-block-move"

PARAMS = {
    "title": "Block move: a unit mass from x = 0 to x = 1 in 1 s, rest to rest, least integral of force squared",
    "states": [{"name": "x", "initial": 0.0, "final": 1.0}, {"name": "v", "initial": 0.0, "final": 0.0}],
    "controls": [{"name": "u", "scale": 6.0}],
    "time": {"initial": 0.0, "final": 1.0},
    "dynamics": {"x": "v", "v": "u"},
    "objective": {"sense": "minimize", "integrand": "u**2"},
    "transcription": {"method": "multiple_shooting", "intervals": 10, "control": "linear", "substeps": 1},
}

PRESET = {
    "description": "Block move, the first example of Kelly, 'An Introduction to Trajectory Optimization: How "
                   "to Do Your Own Direct Collocation', SIAM Review 59(4), 2017, sec. 2: x' = v, v' = u from "
                   "x = 0 to x = 1 in 1 s, rest to rest, minimize int u^2 dt. Kelly gives the analytic "
                   "solution u = 6 - 12 t, so the optimum is int (6 - 12t)^2 dt = 12.0. The optimal control "
                   "is linear in time, so 10 intervals of linear control represent it exactly and RK4 "
                   "integrates the cubic state exactly; tolerance 1e-8.",
    "optimum": 12.0, "tolerance": 1e-8, "params": PARAMS}
