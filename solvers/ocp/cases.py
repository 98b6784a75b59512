"""Presets of the ``ocp`` kind: classic optimal-control problems with published optima, as spec bodies.

Each entry of :data:`PRESETS` is ``{"description", "optimum", "tolerance", "params"}``: ``params``
is a complete ``params`` body of ``../shared/specs/ocp.md`` (one phase, or several in
``params.phases``: the same mechanism); ``optimum`` the published value of
the objective in the user's sense; ``tolerance`` the absolute difference a test allows on the
preset's own grid, with the reason in the description.  Standard library only (the API lists
the presets without loading numpy).

The Betts shuttle (:mod:`solvers.ocp.catalogue.betts_shuttle`) is written in Betts' English units;
its numbers are those of the ``reentry`` kind's ``betts-max-crossrange`` preset, so that both kinds
must agree.
"""
from __future__ import annotations

import math

from solvers.ocp.catalogue.betts_shuttle import BETTS_SHUTTLE
from solvers.ocp.catalogue.bryson_denham import BRYSON_DENHAM
from solvers.ocp.catalogue.hang_glider import HANG_GLIDER

BRACHISTOCHRONE = {
    "title": "Brachistochrone: the wire of fastest descent from (0, 10) m to (10, 5) m",
    "constants": {"g": 9.80665},
    "states": [
        {"name": "x", "initial": 0.0, "final": 10.0, "unit": "m"},
        {"name": "y", "initial": 10.0, "final": 5.0, "unit": "m"},
        {"name": "v", "initial": 0.0, "lower": 0.0, "scale": 10.0, "unit": "m/s"},
    ],
    "controls": [{"name": "theta", "lower": 0.0, "upper": math.pi, "unit": "rad"}],
    "time": {"initial": 0.0, "final": None, "final_lower": 0.5, "final_upper": 10.0, "final_guess": 2.0},
    "dynamics": {"x": "v*sin(theta)", "y": "-v*cos(theta)", "v": "g*cos(theta)"},
    "objective": {"sense": "minimize", "expr": "tf"},
    "transcription": {"method": "multiple_shooting", "intervals": 50, "control": "linear"},
    "guess": {"states": {"v": [0.0, 9.9]}, "controls": {"theta": [0.1, 1.75]}},
}

# COPS 3.0 (Dolan, More, Munson, ANL/MCS-TM-273, 2004), problem 10 "Goddard rocket", after
# Bryson (1999): nondimensional h0 = m0 = g0 = 1.
GODDARD = {
    "title": "Goddard rocket: maximum altitude (COPS 3.0 problem 10)",
    "constants": {"Tmax": 3.5, "Dc": 310.0, "hc": 500.0, "c": 0.5},
    "states": [{"name": "h", "initial": 1.0, "lower": 1.0},
               {"name": "v", "initial": 0.0, "lower": 0.0, "scale": 0.1},
               {"name": "m", "initial": 1.0, "final": 0.6, "lower": 0.6, "upper": 1.0}],
    "controls": [{"name": "T", "lower": 0.0, "upper": 3.5}],
    "time": {"initial": 0.0, "final": None, "final_lower": 0.01, "final_upper": 1.0, "final_guess": 0.2},
    "expressions": {"drag": "Dc*v**2*exp(-hc*(h - 1))", "grav": "1/h**2"},
    "dynamics": {"h": "v", "v": "(T - drag)/m - grav", "m": "-T/c"},
    "objective": {"sense": "maximize", "expr": "final(h)"},
    "transcription": {"method": "multiple_shooting", "intervals": 100, "control": "constant", "substeps": 2},
    "guess": {"states": {"h": [1.0, 1.01], "v": [0.0, 0.05], "m": [1.0, 0.6]},
              "controls": {"T": [1.75, 1.75]}},
}

PRESETS: dict[str, dict] = {
    "brachistochrone": {
        "description": "Brachistochrone (the Dymos and GPOPS-II example): a bead slides without friction "
                       "from (0, 10) m at rest to x = 10 m, y = 5 m under g = 9.80665 m/s^2; the control is "
                       "the wire's angle from the downward vertical. Published minimum time 1.8016 s "
                       "(Dymos docs, GPOPS-II manual). Tolerance 1e-4 s: 50 intervals of RK4 with linear "
                       "controls give 1.80160 s.",
        "optimum": 1.8016, "tolerance": 1e-4, "params": BRACHISTOCHRONE},
    "betts-shuttle-ocp": {
        "description": "Space Shuttle reentry, maximum crossrange: Betts, Practical Methods for Optimal "
                       "Control, 2nd ed., sec. 6.3 (no heating limit), written as ocp expressions in Betts' "
                       "English units (aero polynomials in alpha degrees, exponential atmosphere, spherical "
                       "non-rotating Earth; the heating rate is reported as an expression). Betts: 34.1412 "
                       "deg, tf 2008.59 s; the reentry kind's betts-max-crossrange on the same grid (100 "
                       "intervals, linear controls, 2 RK4 steps): 34.14118 deg; this preset gives 34.14118 "
                       "deg, tf 2008.59 s. Tolerance 0.01 deg.",
        "optimum": 34.1412, "tolerance": 0.01, "params": BETTS_SHUTTLE},
    "bryson-denham": {
        "description": "Bryson-Denham problem: Bryson & Ho, Applied Optimal Control (1975), sec. 3.11: "
                       "x' = v, v' = u, x(0) = x(1) = 0, v(0) = -v(1) = 1, minimize int u^2/2 dt with the "
                       "state limit x <= l = 1/9. Analytic optimum J = 4/(9 l) = 4 (the limit is touched on "
                       "[3l, 1 - 3l]). 90 intervals give 4.0000000 (the corners of u at t = 1/3 and 2/3 "
                       "fall on nodes, and the limit holds between the nodes too); tolerance 1e-4.",
        "optimum": 4.0, "tolerance": 1e-4, "params": BRYSON_DENHAM},
    "goddard-rocket": {
        "description": "Goddard rocket, maximum altitude: COPS 3.0 (Dolan, More & Munson 2004) problem 10, "
                       "after Bryson, Dynamic Optimization (1999); nondimensional (h0 = m0 = g0 = 1, "
                       "Tmax = 3.5, final mass 0.6, drag 310 v^2 exp(-500 (h - 1))). Published final "
                       "altitude 1.01283. 100 intervals of piecewise-constant thrust give 1.012837 (the "
                       "singular thrust arc resolved to about 1e-5); tolerance 1e-4.",
        "optimum": 1.01283, "tolerance": 1e-4, "params": GODDARD},
    "hang-glider": {
        "description": "Hang glider, maximum range through a thermal updraft: COPS 3.0 (Dolan, More & "
                       "Munson 2004) problem 11, after Bulirsch, Nerz, Pesch & von Stryk (1993). Published "
                       "final range 1248.03 m. 100 intervals give 1247.99 m (the lift-coefficient history "
                       "turns sharply near the thermal); tolerance 0.2 m.",
        "optimum": 1248.03, "tolerance": 0.2, "params": HANG_GLIDER},
}


# --- several phases (params.phases), posed in the same form --------------------------------------
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

PRESETS.update({
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
})

# The literature catalogue (issue 35 item 7): solvers/ocp/catalogue/, one module per problem.
# After PRESETS exists; the catalogue never imports this module.
from solvers.ocp.catalogue import CATALOGUE  # noqa: E402 (after PRESETS, as said above)
from solvers.ocp.robust.presets import ROBUST_PRESETS  # noqa: E402 (robust design, with their twins)

PRESETS.update(CATALOGUE)
PRESETS.update(ROBUST_PRESETS)
