"""Catalyst mixing in a plug-flow reactor: a bang-singular-bang control (COPS 3.0)."""
from __future__ import annotations

NAME = "catalyst-mixing"

# COPS: x1' = u (10 x2 - x1), x2' = u (x1 - 10 x2) - (1 - u) x2, x(0) = (1, 0), 0 <= u <= 1,
# minimize -1 + x1(1) + x2(1) (maximize the yield of S3).  Gunn & Thomas (1965).
PARAMS = {
    "title": "Catalyst mixing: the mixing policy of two catalysts that maximizes the yield (COPS 3.0)",
    "states": [{"name": "x1", "initial": 1.0}, {"name": "x2", "initial": 0.0, "scale": 0.1}],
    "controls": [{"name": "u", "lower": 0.0, "upper": 1.0}],
    "time": {"initial": 0.0, "final": 1.0},
    "dynamics": {"x1": "u*(10*x2 - x1)", "x2": "u*(x1 - 10*x2) - (1 - u)*x2"},
    "objective": {"sense": "minimize", "expr": "-1 + final(x1) + final(x2)"},
    "transcription": {"method": "multiple_shooting", "intervals": 100, "control": "constant", "substeps": 2},
    "guess": {"controls": {"u": [0.5, 0.5]}},
}

PRESET = {
    "description": "Catalyst mixing (Gunn & Thomas 1965): COPS 3.0 (Dolan, More & Munson, ANL/MCS-TM-273, "
                   "2004): x1' = u (10 x2 - x1), x2' = u (x1 - 10 x2) - (1 - u) x2, x(0) = (1, 0), 0 <= u <= 1, "
                   "minimize -1 + x1(1) + x2(1). The control is bang-singular-bang (u = 1, a singular arc, "
                   "then u = 0). COPS 3.0 reports -0.0480556 (collocation; COPS 2.0 Table 14.2: -0.0480559 "
                   "on 800 trapezoidal intervals). 100 intervals of constant control place both switches "
                   "within an interval of 0.01, which shifts the yield by ~1e-6; tolerance 5e-6.",
    "optimum": -0.0480556, "tolerance": 5e-6, "params": PARAMS}
