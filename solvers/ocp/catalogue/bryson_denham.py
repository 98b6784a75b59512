"""Bryson-Denham's double integrator under a state limit as an ``ocp`` body, which the ``bryson-denham`` preset
(:mod:`solvers.ocp.cases`) poses as it is and ``bryson-denham-robust`` (:mod:`solvers.ocp.robust.presets`) with
an uncertain initial speed.  Standard library only."""
from __future__ import annotations

from typing import Any

# Bryson & Ho, Applied Optimal Control (1975), sec. 3.11, example 1: state inequality x <= l.
BRYSON_DENHAM: dict[str, Any] = {
    "title": "Bryson-Denham: double integrator with a state limit x <= 1/9",
    "constants": {"l": 1.0 / 9.0},
    "states": [{"name": "x", "initial": 0.0, "final": 0.0, "scale": 0.1},
               {"name": "v", "initial": 1.0, "final": -1.0}],
    "controls": [{"name": "u", "scale": 10.0}],
    "time": {"initial": 0.0, "final": 1.0},
    "dynamics": {"x": "v", "v": "u"},
    "path": [{"name": "x_limit", "expr": "x", "upper": 1.0 / 9.0}],
    "objective": {"sense": "minimize", "integrand": "0.5*u**2"},
    "transcription": {"method": "multiple_shooting", "intervals": 90, "control": "linear", "substeps": 2},
}
