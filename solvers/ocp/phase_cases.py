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

# A two-stage sounding rocket flying straight up in vacuum under uniform gravity: stage 1 burns its
# propellant, its 100 kg structure drops (the link), stage 2 burns, then the coast to apogee.
# Without drag, full thrust is optimal (the gravity loss g * burn time is least), so the apogee
# follows from Tsiolkovsky's equation and its integral in closed form (tests/unit/test_ocp_phases.py).
TWO_STAGE = {
    "title": "Two-stage vertical ascent to the highest apogee, stage 1's structure dropped at burnout",
    "constants": {"g": 9.80665, "T1": 30000.0, "ve1": 2500.0, "T2": 6000.0, "ve2": 3000.0, "dry1": 100.0},
    "phases": [
        {"name": "stage1",
         "states": [{"name": "h", "initial": 0.0, "scale": 1e5, "unit": "m"},
                    {"name": "v", "initial": 0.0, "scale": 1e3, "unit": "m/s"},
                    {"name": "m", "initial": 1000.0, "final": 400.0, "lower": 400.0, "upper": 1000.0,
                     "unit": "kg"}],
         "controls": [{"name": "T", "lower": 0.0, "upper": 30000.0, "unit": "N"}],
         "time": {"initial": 0.0, "final_upper": 400.0},
         "dynamics": {"h": "v", "v": "T/m - g", "m": "-T/ve1"},
         "transcription": {"method": "multiple_shooting", "intervals": 20, "substeps": 2},
         "guess": {"tf": 60.0, "states": {"h": [0.0, 3e4], "v": [0.0, 1500.0]}, "controls": {"T": [25000.0, 25000.0]}}},
        {"name": "stage2",
         "states": [{"name": "h", "scale": 1e5, "unit": "m"}, {"name": "v", "scale": 1e3, "unit": "m/s"},
                    {"name": "m", "final": 100.0, "lower": 100.0, "upper": 300.0, "unit": "kg"}],
         "controls": [{"name": "T", "lower": 0.0, "upper": 6000.0, "unit": "N"}],
         "time": {"final_upper": 800.0},
         "dynamics": {"h": "v", "v": "T/m - g", "m": "-T/ve2"},
         "transcription": {"method": "multiple_shooting", "intervals": 20, "substeps": 2},
         "guess": {"tf": 170.0, "states": {"h": [3e4, 3e5], "v": [1500.0, 4000.0], "m": [300.0, 100.0]},
                   "controls": {"T": [5000.0, 5000.0]}}},
        {"name": "coast",
         "states": [{"name": "h", "scale": 1e5, "unit": "m"}, {"name": "v", "scale": 1e3, "unit": "m/s"}],
         "time": {"final_upper": 2000.0},
         "dynamics": {"h": "v", "v": "-g"},
         "transcription": {"method": "multiple_shooting", "intervals": 10, "substeps": 2},
         "guess": {"tf": 600.0, "states": {"h": [3e5, 1.2e6], "v": [4000.0, 0.0]}}},
    ],
    "links": [{"name": "stage1_drop", "expr": 'initial(m, "stage2") - final(m, "stage1") + dry1', "lower": 0.0,
               "upper": 0.0}],
    "objective": {"sense": "maximize", "expr": 'final(h, "coast")'},
}

# Meditch's soft lunar landing (Meditch, IEEE Trans. Automatic Control 9(4), 1964, 477-484): the
# minimum-fuel vertical descent is a free fall followed by a full-thrust burn to touchdown at rest.
# Posed as a coast phase (motor off) and a burn phase whose thrust the optimizer chooses.
LANDER = {
    "title": "Soft lunar landing with least propellant: coast, then burn to touchdown at rest (Meditch 1964)",
    "constants": {"g": 1.62, "Tmax": 4000.0, "ve": 3000.0},
    "phases": [
        {"name": "coast",
         "states": [{"name": "h", "initial": 2000.0, "lower": 0.0, "scale": 1000.0, "unit": "m"},
                    {"name": "v", "initial": -50.0, "scale": 100.0, "unit": "m/s"},
                    {"name": "m", "initial": 1000.0, "lower": 100.0, "upper": 1000.0, "unit": "kg"}],
         "time": {"initial": 0.0, "final_upper": 200.0},
         "dynamics": {"h": "v", "v": "-g", "m": "0"},
         "transcription": {"method": "multiple_shooting", "intervals": 10, "substeps": 2},
         "guess": {"tf": 15.0, "states": {"h": [2000.0, 1000.0], "v": [-50.0, -75.0]}}},
        {"name": "burn",
         "states": [{"name": "h", "final": 0.0, "lower": 0.0, "scale": 1000.0, "unit": "m"},
                    {"name": "v", "final": 0.0, "scale": 100.0, "unit": "m/s"},
                    {"name": "m", "lower": 100.0, "upper": 1000.0, "unit": "kg"}],
         "controls": [{"name": "T", "lower": 0.0, "upper": 4000.0, "unit": "N"}],
         "time": {"final_upper": 400.0},
         "dynamics": {"h": "v", "v": "T/m - g", "m": "-T/ve"},
         "transcription": {"method": "multiple_shooting", "intervals": 30, "substeps": 2},
         "guess": {"tf": 45.0, "states": {"h": [1000.0, 0.0], "v": [-75.0, 0.0], "m": [1000.0, 950.0]},
                   "controls": {"T": [4000.0, 4000.0]}}},
    ],
    "objective": {"sense": "maximize", "expr": 'final(m, "burn")'},
}

PHASE_PRESETS: dict[str, dict] = {
    "goddard-three-phases": {
        "description": "Goddard rocket, maximum altitude, in its switching structure: full thrust, singular "
                       "arc, coast. COPS 3.0 (Dolan, More & Munson 2004) problem 10 after Bryson, Dynamic "
                       "Optimization (1999) sec. 9.3, the goddard-rocket preset's problem (nondimensional, "
                       "Tmax = 3.5, final mass 0.6). Published final altitude 1.01283. The switching times are "
                       "decision variables, so no interval straddles a switch.",
        "optimum": 1.01283, "tolerance": 1e-4, "params": GODDARD_3},
    "two-stage-ascent": {
        "description": "Two-stage sounding rocket, highest apogee, straight up in vacuum under uniform gravity "
                       "g = 9.80665 m/s^2: 1000 kg at liftoff, stage 1 burns 600 kg (at most 30 kN, exhaust "
                       "2500 m/s), its 100 kg structure is dropped (a link: initial(m, stage2) = final(m, stage1) "
                       "- 100 kg), stage 2 burns 200 kg (at most 6 kN, exhaust 3000 m/s), then coasts. Without "
                       "drag full thrust is optimal (the gravity loss g t_burn is least), so the optimum follows "
                       "in closed form from Tsiolkovsky's rocket equation integrated once more for the altitude "
                       "(computed independently in tests/unit/test_ocp_phases.py): apogee 1166190.27 m at t = 569.671 s, burnouts at 50 s "
                       "and 150 s. Tolerance 0.5 m: RK4 on 20 intervals per burn resolves ln(m) to ~1e-8.",
        "optimum": 1166190.27, "tolerance": 0.5, "params": TWO_STAGE},
    "lunar-lander-coast-burn": {
        "description": "Soft lunar landing with least propellant: Meditch, IEEE Trans. Automatic Control 9(4) "
                       "(1964): a free fall then a full-thrust burn to touchdown at rest. From 2000 m descending "
                       "at 50 m/s, 1000 kg, g = 1.62 m/s^2, at most 4 kN, exhaust 3000 m/s: coast 14.4627 s, burn "
                       "29.8286 s, final mass 960.2285 kg (the switch point solved in closed form, the burn at "
                       "full thrust). The burn's thrust is the optimizer's choice; tolerance 1e-3 kg.",
        "optimum": 960.2285, "tolerance": 1e-3, "params": LANDER},
}
