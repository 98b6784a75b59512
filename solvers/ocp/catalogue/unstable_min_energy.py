"""Minimum-energy control of an unstable first-order system over 20 s (issue 35 item 5)."""
from __future__ import annotations

import math

NAME = "unstable-min-energy"

# x' = a x + u with a = 2 (an eigenvalue of +2), x(0) = 1, x(T) = 0, minimize int u^2 / 2 dt.
# The costate is lambda = c exp(-a t), u = -lambda; x(T) = 0 gives c = 2 a x0 / (1 - exp(-2aT)) and
# J = a x0^2 / (1 - exp(-2aT)).  T = 20 s, the horizon of the issue's unstable problem: Betts' Alp rider
# (Practical Methods for Optimal Control, 3rd ed., example 10.1, sec. 4.11; J* = 2030.85609), a stiff
# system with eigenvalues -10, -2, -8 and +2 kept above a terrain, whose +2 mode this isolates with a
# closed form.  The dynamics amplify by exp(40) = 2.4e17 over it, so the re-flight from t0 diverges
# whatever the answer and the answer is verified interval by interval (solvers/ocp/growth.py).  The Alp
# rider itself, LGL 40 x 4 with accuracy 1e-3, verified the same way, reaches 2031.0150 (7.8e-5 above
# Betts) in 4 rounds, but needs ~1000 IPOPT iterations in its first round: too slow and too close to
# IPOPT's iteration limit for a preset a test holds.
_A, _T = 2.0, 20.0
OPTIMUM = _A / (1.0 - math.exp(-2 * _A * _T))

PARAMS = {
    "title": "Unstable first-order system x' = 2x + u driven to 0 in 20 s with least energy",
    "constants": {"a": _A},
    "states": [{"name": "x", "initial": 1.0, "final": 0.0}],
    "controls": [{"name": "u", "scale": 4.0}],
    "time": {"initial": 0.0, "final": _T},
    "dynamics": {"x": "a*x + u"},
    "objective": {"sense": "minimize", "integrand": "0.5*u**2"},
    "transcription": {"method": "multiple_shooting", "intervals": 200, "control": "linear", "substeps": 2},
}

PRESET = {
    "description": "Minimum-energy control of an unstable system (the linear-quadratic two-point boundary-value "
                   "problem of Bryson & Ho, Applied Optimal Control, 1975, ch. 5): x' = 2x + u, x(0) = 1, "
                   "x(20) = 0, minimize int u^2/2 dt. The costate decays as exp(-2t) and the closed form is "
                   f"J = a x0^2 / (1 - exp(-2 a T)) = 2/(1 - exp(-80)) = {OPTIMUM!r}. The dynamics amplify "
                   "by exp(40) = 2.4e17 over the horizon: no re-flight from t0 can follow any answer, so it is "
                   "verified interval by interval (verification.mode, with the growth figure). RK4 on 200 "
                   "intervals of linear control (h = 0.05 s, h*a = 0.1) gives 2.0000030, 3e-6 above the closed "
                   "form (5.1e-5 at 100 intervals: fourth order); tolerance 1e-5.",
    "optimum": OPTIMUM, "tolerance": 1e-5, "params": PARAMS}
