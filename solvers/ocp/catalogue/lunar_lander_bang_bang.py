"""Meditch's soft lunar landing in one phase: the optimizer finds the coast-burn switch itself."""
from __future__ import annotations

NAME = "lunar-lander-bang-bang"

PARAMS = {
    "title": "Soft lunar landing with least propellant in one phase: thrust free in [0, 4 kN] (Meditch 1964)",
    "constants": {"g": 1.62, "Tmax": 4000.0, "ve": 3000.0},
    "states": [{"name": "h", "initial": 2000.0, "final": 0.0, "lower": 0.0, "scale": 1000.0, "unit": "m"},
               {"name": "v", "initial": -50.0, "final": 0.0, "scale": 100.0, "unit": "m/s"},
               {"name": "m", "initial": 1000.0, "lower": 100.0, "upper": 1000.0, "unit": "kg"}],
    "controls": [{"name": "T", "lower": 0.0, "upper": 4000.0, "scale": 4000.0, "unit": "N"}],
    "time": {"initial": 0.0, "final": None, "final_lower": 10.0, "final_upper": 200.0, "final_guess": 45.0},
    "dynamics": {"h": "v", "v": "T/m - g", "m": "-T/ve"},
    "objective": {"sense": "maximize", "expr": "final(m)"},
    "transcription": {"method": "multiple_shooting", "intervals": 60, "control": "constant", "substeps": 2},
    "guess": {"states": {"h": [2000.0, 0.0], "v": [-50.0, 0.0], "m": [1000.0, 960.0]},
              "controls": {"T": [2000.0, 2000.0]}},
}

PRESET = {
    "description": "Soft lunar landing with least propellant, one phase: Meditch, IEEE Trans. Automatic "
                   "Control 9(4), 1964: the minimum-fuel vertical descent is a free fall then a full-thrust "
                   "burn (bang-bang). Same data as the lunar-lander-coast-burn preset (2000 m, -50 m/s, "
                   "1000 kg, g = 1.62 m/s^2, at most 4 kN, exhaust 3000 m/s), whose closed-form switch gives "
                   "the final mass 960.2285 kg. Here the thrust is free on 60 equal intervals of constant "
                   "thrust, so the switch (t = 14.4627 s) falls inside an interval and the optimizer "
                   "blends it there with an intermediate thrust; that costs propellant of the order of the "
                   "interval length times the gravity loss. Tolerance 0.05 kg.",
    "optimum": 960.2285, "tolerance": 0.05, "params": PARAMS}
