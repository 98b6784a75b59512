"""A scalar linear-quadratic regulator with a free final state: the Riccati equation in closed form."""
from __future__ import annotations

import math

NAME = "scalar-lq-riccati"

# x' = a x + u (a = 1, unstable), x(0) = 1, T = 1, minimize int (q x^2 + r u^2)/2 dt with q = r = 1 and
# x(T) free.  The optimal cost is p(0) x0^2 / 2 with the Riccati equation p' = p^2/r - 2 a p - q,
# p(T) = 0, whose roots are p1,2 = 1 +- sqrt(2); then (p - p1)/(p - p2) = C exp((p1 - p2) t).
_P1, _P2, _T = 1 + math.sqrt(2), 1 - math.sqrt(2), 1.0
_K = (_P1 / _P2) * math.exp(-(_P1 - _P2) * _T)
OPTIMUM = 0.5 * (_P1 - _K * _P2) / (1 - _K)

PARAMS = {
    "title": "Scalar LQ regulator: x' = x + u, x(0) = 1, minimize int (x^2 + u^2)/2 over 1 s, final state free",
    "states": [{"name": "x", "initial": 1.0}],
    "controls": [{"name": "u"}],
    "time": {"initial": 0.0, "final": _T},
    "dynamics": {"x": "x + u"},
    "objective": {"sense": "minimize", "integrand": "0.5*(x**2 + u**2)"},
    "transcription": {"method": "multiple_shooting", "intervals": 20, "control": "linear", "substeps": 2},
}

PRESET = {
    "description": "Scalar linear-quadratic regulator with a free final state (Bryson & Ho, Applied Optimal "
                   "Control, 1975, ch. 5: the Riccati equation): x' = x + u, x(0) = 1, minimize "
                   "int (x^2 + u^2)/2 dt over 1 s. The optimal cost is p(0)/2 with p' = p^2 - 2p - 1, "
                   "p(1) = 0, solved in closed form through its roots 1 +- sqrt(2): "
                   f"{OPTIMUM!r}. Smooth control, RK4 on 20 intervals: ~1e-8; tolerance 1e-7.",
    "optimum": OPTIMUM, "tolerance": 1e-7, "params": PARAMS}
