"""Multi-phase presets of the ``ocp`` kind (``params.phases``), each citing its source and optimum.

Merged into :data:`solvers.ocp.cases.PRESETS`.  Standard library only.
"""
from __future__ import annotations

_GODDARD_CONSTANTS = {"Tmax": 3.5, "Dc": 310.0, "hc": 500.0, "c": 0.5}
_GODDARD_EXPRESSIONS = {"drag": "Dc*v**2*exp(-hc*(h - 1))", "grav": "1/h**2"}


def _goddard_states(m_final=None):
    return [{"name": "h", "lower": 1.0}, {"name": "v", "lower": 0.0, "scale": 0.1},
            {"name": "m", "lower": 0.6, "upper": 1.0, **({"final": m_final} if m_final else {})}]


# COPS 3.0 problem 10 (the goddard-rocket preset) posed in its known switching structure
# (Bryson, Dynamic Optimization, 1999, sec. 9.3; Seywald & Cliff 1993): full thrust, a singular
# arc of intermediate thrust, then a coast with the motor off.
GODDARD_3 = {
    "title": "Goddard rocket in three phases: full thrust, singular arc, coast (COPS 3.0 problem 10)",
    "constants": _GODDARD_CONSTANTS,
    "phases": [
        {"name": "boost",
         "states": [{"name": "h", "initial": 1.0, "lower": 1.0}, {"name": "v", "initial": 0.0, "lower": 0.0,
                                                                  "scale": 0.1},
                    {"name": "m", "initial": 1.0, "lower": 0.6, "upper": 1.0}],
         "time": {"initial": 0.0, "final_upper": 1.0},
         "expressions": _GODDARD_EXPRESSIONS,
         "dynamics": {"h": "v", "v": "(Tmax - drag)/m - grav", "m": "-Tmax/c"},
         "transcription": {"method": "multiple_shooting", "intervals": 10, "substeps": 4},
         "guess": {"tf": 0.02, "states": {"h": [1.0, 1.001], "v": [0.0, 0.08], "m": [1.0, 0.86]}}},
        {"name": "singular",
         "states": _goddard_states(m_final=0.6),
         "controls": [{"name": "T", "lower": 0.0, "upper": 3.5}],
         "time": {"final_upper": 1.0},
         "expressions": _GODDARD_EXPRESSIONS,
         "dynamics": {"h": "v", "v": "(T - drag)/m - grav", "m": "-T/c"},
         "transcription": {"method": "multiple_shooting", "intervals": 40, "control": "linear", "substeps": 2},
         "guess": {"tf": 0.07, "states": {"h": [1.001, 1.006], "v": [0.08, 0.1], "m": [0.86, 0.6]},
                   "controls": {"T": [2.0, 1.0]}}},
        {"name": "coast",
         "states": _goddard_states(),
         "time": {"final_upper": 1.0},
         "expressions": _GODDARD_EXPRESSIONS,
         "dynamics": {"h": "v", "v": "-drag/m - grav", "m": "0"},
         "transcription": {"method": "multiple_shooting", "intervals": 40, "substeps": 2},
         "guess": {"tf": 0.2, "states": {"h": [1.006, 1.0128], "v": [0.1, 0.0], "m": [0.6, 0.6]}}},
    ],
    "objective": {"sense": "maximize", "expr": 'final(h, "coast")'},
}

PHASE_PRESETS: dict[str, dict] = {
    "goddard-three-phases": {
        "description": "Goddard rocket, maximum altitude, in its switching structure: full thrust, singular "
                       "arc, coast. COPS 3.0 (Dolan, More & Munson 2004) problem 10 after Bryson, Dynamic "
                       "Optimization (1999) sec. 9.3, the goddard-rocket preset's problem (nondimensional, "
                       "Tmax = 3.5, final mass 0.6). Published final altitude 1.01283. The switching times are "
                       "decision variables, so no interval straddles a switch.",
        "optimum": 1.01283, "tolerance": 1e-4, "params": GODDARD_3},
}
