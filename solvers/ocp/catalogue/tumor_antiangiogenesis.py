"""Tumor anti-angiogenesis (Ledzewicz & Schaettler): a singular arc, free final time."""
from __future__ import annotations

NAME = "tumor-antiangiogenesis"

# Betts, Practical Methods (3rd ed.) example 10.141, sec. 8.17 (after Ledzewicz & Schaettler):
# p' = -xi p ln(p/q), q' = q (b - (mu + d p^(2/3) + G u)), y' = u; 0 <= u <= a, y(tf) <= A;
# p(0) = pbar/2, q(0) = qbar/4 with pbar = qbar = ((b - mu)/d)^(3/2); minimize p(tf), tf free.
_PBAR = ((5.85 - 0.02) / 0.00873) ** 1.5

PARAMS = {
    "title": "Tumor anti-angiogenesis: least tumor volume with a limited amount of inhibitor (Betts 10.141)",
    "constants": {"xi": 0.084, "b": 5.85, "mu": 0.02, "d": 0.00873, "G": 0.15, "a": 75.0, "A": 15.0},
    "states": [{"name": "p", "initial": _PBAR / 2, "lower": 0.01, "upper": _PBAR, "scale": 1e4},
               {"name": "q", "initial": _PBAR / 4, "lower": 0.01, "upper": _PBAR, "scale": 1e4},
               {"name": "y", "initial": 0.0, "lower": 0.0, "upper": 15.0, "scale": 10.0}],
    "controls": [{"name": "u", "lower": 0.0, "upper": 75.0, "scale": 75.0}],
    "time": {"initial": 0.0, "final": None, "final_lower": 0.1, "final_upper": 5.0, "final_guess": 1.2},
    "dynamics": {"p": "-xi*p*log(p/q)", "q": "q*(b - (mu + d*p**(2/3) + G*u))", "y": "u"},
    "objective": {"sense": "minimize", "expr": "final(p)"},
    "transcription": {"method": "multiple_shooting", "intervals": 400, "control": "constant", "substeps": 2},
    "guess": {"states": {"p": [_PBAR / 2, 7600.0], "q": [_PBAR / 4, 7600.0], "y": [0.0, 15.0]},
              "controls": {"u": [20.0, 20.0]}},
}

PRESET = {
    "description": "Tumor anti-angiogenesis (Ledzewicz & Schaettler): Betts, Practical Methods for Optimal Control "
                   "(3rd ed.), example 10.141 (sec. 8.17): tumor volume p and carrying capacity q, "
                   "inhibitor dose u in [0, 75] with total y(tf) <= 15, free final time; minimize p(tf). "
                   "The control is full dose, a singular arc, then no dose. Betts: p(tf) = 7571.6712 at "
                   "tf = 1.1961336 (as quoted from the book by the opty example set). The junctions of the "
                   "singular arc fall inside intervals of constant dose: 100, 200 and 400 intervals are "
                   "above Betts' value by 0.082, 0.025 and 0.0014; 400 intervals, tolerance 0.01 "
                   "(1.3e-6 relative).",
    "optimum": 7571.6712, "tolerance": 0.01, "params": PARAMS}
