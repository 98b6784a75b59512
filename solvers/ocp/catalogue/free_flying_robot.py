"""Sakawa's free-flying robot: least fuel (an L1 cost) with four on-off thrusters."""
from __future__ import annotations

import math

NAME = "free-flying-robot"

PARAMS = {
    "title": "Free-flying robot: least fuel from (-10, -10) to rest at the origin in 12 s (Betts 10.43, Sakawa 1999)",
    "constants": {"alpha": 0.2, "beta": 0.2},
    "states": [{"name": "x", "initial": -10.0, "final": 0.0, "scale": 10.0},
               {"name": "y", "initial": -10.0, "final": 0.0, "scale": 10.0},
               {"name": "theta", "initial": math.pi / 2, "final": 0.0},
               {"name": "vx", "initial": 0.0, "final": 0.0}, {"name": "vy", "initial": 0.0, "final": 0.0},
               {"name": "omega", "initial": 0.0, "final": 0.0}],
    "controls": [{"name": f"u{i}", "lower": 0.0, "upper": 1.0} for i in range(1, 5)],
    "time": {"initial": 0.0, "final": 12.0},
    "expressions": {"thrust": "u1 - u2 + u3 - u4"},
    "dynamics": {"x": "vx", "y": "vy", "theta": "omega", "vx": "thrust*cos(theta)", "vy": "thrust*sin(theta)",
                 "omega": "alpha*(u1 - u2) - beta*(u3 - u4)"},
    "path": [{"name": "pair_1", "expr": "u1 + u2", "upper": 1.0}, {"name": "pair_2", "expr": "u3 + u4", "upper": 1.0}],
    "objective": {"sense": "minimize", "integrand": "u1 + u2 + u3 + u4"},
    "transcription": {"method": "multiple_shooting", "intervals": 240, "control": "constant", "substeps": 2},
    "guess": {"states": {"x": [-10.0, 0.0], "y": [-10.0, 0.0], "theta": [math.pi / 2, 0.0]},
              "controls": {"u1": [0.2, 0.2], "u2": [0.2, 0.2], "u3": [0.2, 0.2], "u4": [0.2, 0.2]}},
}

PRESET = {
    "description": "Free-flying robot (Sakawa, Optimal Control Applications and Methods 20, 1999): Betts, "
                   "Practical Methods for Optimal Control (3rd ed.), example 10.43 (sec. 8.13): two pairs of "
                   "thrusters u1..u4 in [0, 1], each pair at most 1, move the robot from (-10, -10) at "
                   "heading pi/2 to rest at the origin in 12 s with least fuel int (u1 + u2 + u3 + u4) dt "
                   "(an L1 cost: the thrusts are bang-bang). Betts: 7.91055654 (as quoted from the book by "
                   "the opty example set). The thrusters switch inside intervals of constant thrust: 120, "
                   "240 and 480 intervals miss Betts' value by +2.3e-3, +1.5e-4 and -1.0e-4; 240 intervals, "
                   "tolerance 1e-3.",
    "optimum": 7.91055654, "tolerance": 1e-3, "params": PARAMS}
