"""Rao and Mease's hyper-sensitive problem (short horizon, as in the PROPT example set)."""
from __future__ import annotations

NAME = "hypersensitive"

PARAMS = {
    "title": "Hyper-sensitive problem: x' = -x^3 + u, x(0) = 1, x(10) = 1.5 (Rao & Mease 2000)",
    "states": [{"name": "x", "initial": 1.0, "final": 1.5}],
    "controls": [{"name": "u"}],
    "time": {"initial": 0.0, "final": 10.0},
    "dynamics": {"x": "-x**3 + u"},
    "objective": {"sense": "minimize", "integrand": "x**2 + u**2"},
    "transcription": {"method": "multiple_shooting", "intervals": 400, "control": "linear", "substeps": 2},
}

PRESET = {
    "description": "Hyper-sensitive problem: Rao & Mease, Optimal Control Applications and Methods 21(1), 2000, "
                   "sec. 3.1, in the form of the TOMLAB/PROPT example set (example 51): x' = -x^3 + u, "
                   "x(0) = 1, x(10) = 1.5, minimize int (x^2 + u^2) dt. PROPT: 6.723925391 (50 "
                   "collocation points, SNOPT). The solution leaves and joins the slow manifold x = 0 in "
                   "boundary layers of width ~1 at both ends. RK4's h^4 shows: 100, 200 and 400 "
                   "intervals of linear control miss the PROPT value by 1.4e-3, 9.6e-5 and 6.0e-6 (ratios "
                   "of 16, so the continuous optimum agrees with PROPT's to ~4e-7); 400 intervals, "
                   "tolerance 1e-5.",
    "optimum": 6.723925391, "tolerance": 1e-5, "params": PARAMS}
