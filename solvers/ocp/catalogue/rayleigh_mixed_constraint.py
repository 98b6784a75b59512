"""The Rayleigh problem with a mixed state-control constraint (Maurer & Augustin; Betts 10.113)."""
from __future__ import annotations

NAME = "rayleigh-mixed-constraint"

PARAMS = {
    "title": "Rayleigh oscillator with the mixed constraint u + x1/6 <= 0 (Betts 10.113)",
    "constants": {"p": 0.14},
    "states": [{"name": "x1", "initial": -5.0, "scale": 5.0}, {"name": "x2", "initial": -5.0, "scale": 5.0}],
    "controls": [{"name": "u"}],
    "time": {"initial": 0.0, "final": 4.5},
    "dynamics": {"x1": "x2", "x2": "-x1 + x2*(1.4 - p*x2**2) + 4*u"},
    "path": [{"name": "mixed", "expr": "u + x1/6", "upper": 0.0}],
    "objective": {"sense": "minimize", "integrand": "u**2 + x1**2"},
    "transcription": {"method": "multiple_shooting", "intervals": 360, "control": "linear", "substeps": 2},
}

PRESET = {
    "description": "Rayleigh problem with a mixed state-control constraint: Maurer & Augustin (2001), Betts, "
                   "Practical Methods for Optimal Control (3rd ed.), example 10.113: x1' = x2, "
                   "x2' = -x1 + x2 (1.4 - 0.14 x2^2) + 4u, x(0) = (-5, -5), tf = 4.5, u + x1/6 <= 0, "
                   "minimize int (u^2 + x1^2) dt. Betts: 44.8044433 (as quoted from the book by the opty "
                   "example set). The constraint is active on an arc whose junctions fall inside intervals, "
                   "which makes the error second order: 90, 180 and 360 intervals of linear control are "
                   "above Betts' value by 4.5e-3, 1.1e-3 and 2.9e-4 (ratios of 4; Richardson's "
                   "extrapolation of the last two lands 2e-6 from it); 360 intervals, tolerance 5e-4.",
    "optimum": 44.8044433, "tolerance": 5e-4, "params": PARAMS}
