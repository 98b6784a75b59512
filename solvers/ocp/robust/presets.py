"""Robust-design presets of the ``ocp`` kind, each with its deterministic twin (the same params without
``uncertainty`` and ``robust``), merged into :data:`solvers.ocp.cases.PRESETS`.  Each description states
the cost of robustness: the robust design's objective against the twin's, on the preset's own grid, as
measured by ``tests/unit/test_ocp_robust_presets.py``.  Standard library only.
"""
from __future__ import annotations

import copy

from solvers.ocp.catalogue.betts_shuttle import BETTS_SHUTTLE
from solvers.ocp.catalogue.bryson_denham import BRYSON_DENHAM

# A sounding rocket straight up through an exponential atmosphere: thrust throttled under a dynamic-pressure
# limit, drag area uncertain (10%, normal).  Maximum altitude at t = 120 s.
ROCKET_ASCENT = {
    "title": "Vertical ascent to the highest altitude at 120 s under a 12 kPa dynamic-pressure limit",
    "constants": {"g": 9.80665, "ve": 2500.0, "rho0": 1.225, "H": 7500.0, "CdA": 0.5},
    "states": [{"name": "h", "initial": 0.0, "lower": 0.0, "scale": 1e5, "unit": "m"},
               {"name": "v", "initial": 0.0, "scale": 1e3, "unit": "m/s"},
               {"name": "m", "initial": 1000.0, "lower": 400.0, "upper": 1000.0, "unit": "kg"}],
    "controls": [{"name": "T", "lower": 0.0, "upper": 20000.0, "unit": "N"}],
    "time": {"initial": 0.0, "final": 120.0},
    "expressions": {"rho": "rho0*exp(-h/H)", "q": "0.5*rho*v**2", "drag": "q*CdA"},
    "dynamics": {"h": "v", "v": "(T - drag)/m - g", "m": "-T/ve"},
    "path": [{"name": "q_limit", "expr": "q", "upper": 12000.0}],
    "objective": {"sense": "maximize", "expr": "final(h)"},
    "transcription": {"method": "multiple_shooting", "intervals": 60, "control": "linear", "substeps": 2},
    "guess": {"states": {"h": [0.0, 3.5e4], "v": [0.0, 0.0], "m": [1000.0, 400.0]}, "controls": {"T": [10000.0, 0.0]}},
}
ROCKET_ASCENT_ROBUST = {
    **copy.deepcopy(ROCKET_ASCENT),
    "title": "Robust vertical ascent: the 12 kPa dynamic-pressure limit held at mean + 3 sigma of an uncertain drag",
    "uncertainty": {"parameters": {"CdA": {"distribution": "normal", "sigma": 0.05}}},
    "robust": {"k": 3.0, "objective": "mean", "constraints": ["q_limit"], "monte_carlo": {"samples": 2000}},
}


# Bryson & Ho, Applied Optimal Control (1975), sec. 2.7: the largest circular orbit reached in a fixed time by a
# constant thrust whose direction is steered (normalized: mu = 1, r0 = 1, thrust 0.1405, mass flow 0.0749,
# tf = 3.32), its final radial speed and circular speed held within a band of 0.01.
ORBIT_RAISING = {
    "title": "Orbit raising: the largest near-circular orbit in a fixed time, the final conditions within 0.01",
    "constants": {"mu": 1.0, "T": 0.1405, "mdot": 0.0749},
    "states": [{"name": "r", "initial": 1.0, "lower": 0.5, "upper": 3.0, "scale": 1.0},
               {"name": "vr", "initial": 0.0, "scale": 1.0},
               {"name": "vt", "initial": 1.0, "scale": 1.0}],
    "controls": [{"name": "phi", "lower": -3.2, "upper": 3.2, "scale": 1.0, "unit": "rad"}],
    "time": {"initial": 0.0, "final": 3.32},
    "expressions": {"a": "T/(1 - mdot*t)"},
    "dynamics": {"r": "vr", "vr": "vt**2/r - mu/r**2 + a*sin(phi)", "vt": "-vr*vt/r + a*cos(phi)"},
    "boundary": [{"name": "radial_speed", "expr": "final(vr)", "lower": -0.01, "upper": 0.01},
                 {"name": "circular", "expr": "final(vt) - sqrt(mu/final(r))", "lower": -0.01, "upper": 0.01}],
    "objective": {"sense": "maximize", "expr": "final(r)"},
    "transcription": {"method": "multiple_shooting", "intervals": 50, "control": "linear", "substeps": 2},
    "guess": {"states": {"r": [1.0, 1.5], "vr": [0.0, 0.0], "vt": [1.0, 0.8]}, "controls": {"phi": [0.5, 2.5]}},
}
ORBIT_RAISING_ROBUST = {
    **copy.deepcopy(ORBIT_RAISING),
    "title": "Robust orbit raising: thrust uncertain by 1%, the final radius at mean - 3 sigma, the final band kept",
    "uncertainty": {"parameters": {"T": {"distribution": "normal", "sigma": 0.001405}}},
    "robust": {"k": 3.0, "constraints": ["radial_speed", "circular"], "monte_carlo": {"samples": 2000}},
}


# Bryson & Ho, Applied Optimal Control (1975), sec. 3.11, example 1 (the bryson-denham preset, its twin): a
# double integrator kept under x <= 1/9, its initial speed uncertain.  The dynamics are linear, so CADET's mean and sigma are exact and the Monte Carlo can only
# differ by its sampling error.
BRYSON_DENHAM_ROBUST = {
    **copy.deepcopy(BRYSON_DENHAM),
    "title": "Robust Bryson-Denham: the state limit x <= 1/9 held at mean + 3 sigma of an uncertain initial speed",
    "uncertainty": {"initial": {"v": {"sigma": 0.01}}},
    "robust": {"k": 3.0, "objective": "mean", "constraints": ["x_limit"], "monte_carlo": {"samples": 2000}},
}


def _heat_limited_shuttle() -> dict:
    """Betts' shuttle with the heating limit q <= 70 BTU/ft^2/s and the aerodynamic errors of paper 001
    (``CD = CD_N (1 + s1)``, ``CL = CL_N (1 + s2)``) as constants, zero in the deterministic problem."""
    body = copy.deepcopy(BETTS_SHUTTLE)
    body["title"] = "Space Shuttle reentry, maximum crossrange, heating rate at most 70 BTU/ft^2/s (Betts sec. 6.3)"
    body["constants"].update(s1=0.0, s2=0.0)
    body["expressions"]["CL"] = "(a0 + a1*a_deg)*(1 + s2)"
    body["expressions"]["CD"] = "(b0 + b1*a_deg + b2*a_deg**2)*(1 + s1)"
    body["path"] = [{"name": "heat_limit", "expr": "heat_rate", "upper": 70.0}]
    return body


SHUTTLE_HEAT_LIMITED = _heat_limited_shuttle()
SHUTTLE_HEAT_LIMITED_ROBUST = {
    **copy.deepcopy(SHUTTLE_HEAT_LIMITED),
    "title": "Robust shuttle reentry (paper 001): maximum mean - 3 sigma of the final latitude, the heating limit "
             "held at mean + 3 sigma of uncertain lift and drag",
    "uncertainty": {"parameters": {"s1": {"distribution": "normal", "mean": 0.01, "sigma": 0.01},
                                   "s2": {"distribution": "normal", "mean": -0.01, "sigma": 0.01}}},
    "robust": {"k": 3.0, "constraints": ["heat_limit"], "monte_carlo": {"samples": 10000}},
}

ROBUST_PRESETS: dict[str, dict] = {
    "rocket-ascent-q-limit": {
        "description": "Sounding rocket straight up (1000 kg, 600 kg of propellant, at most 20 kN, exhaust 2500 m/s, "
                       "drag area 0.5 m^2, exponential atmosphere 1.225 kg/m^3, 7.5 km scale height): the highest "
                       "altitude at t = 120 s with the dynamic pressure at most 12 kPa; the throttle rides the limit "
                       "through the dense air. Deterministic twin of rocket-ascent-q-limit-robust: 34356.5 m.",
        "optimum": None, "tolerance": None, "params": ROCKET_ASCENT},
    "rocket-ascent-q-limit-robust": {
        "description": "rocket-ascent-q-limit with the drag area uncertain (normal, sigma 0.05 m^2, 10%): the "
                       "dynamic-pressure limit held at mean + 3 sigma (CADET through the dynamics) and the mean "
                       "altitude maximized, confirmed by 2000 Monte Carlo flights of the open-loop throttle "
                       "(required share Phi(3) = 99.865%; one confirmation round raises the limit's k to about 3.45). "
                       "Cost of robustness: about 1930 m of mean altitude (32427 m against the twin's 34357 m).",
        "optimum": None, "tolerance": None, "params": ROCKET_ASCENT_ROBUST},
    "orbit-raising-band": {
        "description": "Orbit raising after Bryson & Ho, Applied Optimal Control (1975) sec. 2.7 (mu = 1, r0 = 1, "
                       "thrust 0.1405 steered by phi, mass flow 0.0749, tf = 3.32): the largest final radius with the "
                       "final radial speed and the excess over circular speed each within +-0.01. Deterministic "
                       "twin of orbit-raising-uncertain-thrust-robust: final radius 1.5446.",
        "optimum": None, "tolerance": None, "params": ORBIT_RAISING},
    "orbit-raising-uncertain-thrust-robust": {
        "description": "orbit-raising-band with the thrust uncertain (normal, sigma 1%): the final radius maximized "
                       "at mean - 3 sigma and both final conditions held in their band at mean +- 3 sigma (CADET), "
                       "confirmed by 2000 Monte Carlo transfers of the open-loop steering (99.75% and 99.8% kept, "
                       "Phi(3) = 99.865% within the sampling tolerance). Cost of robustness: 0.024 in mean - 3 sigma "
                       "radius (1.5207 against the twin's 1.5446; mean 1.5389, sigma 0.0061 by CADET and by the "
                       "Monte Carlo).",
        "optimum": None, "tolerance": None, "params": ORBIT_RAISING_ROBUST},
    "bryson-denham-robust": {
        "description": "bryson-denham (Bryson & Ho, Applied Optimal Control (1975) sec. 3.11: x' = v, v' = u, "
                       "x(0) = x(1) = 0, v(0) = -v(1) = 1, minimize int u^2/2 dt, x <= 1/9; optimum 4) with the "
                       "initial speed uncertain (normal, sigma 0.01): the state limit held at mean + 3 sigma (the "
                       "dynamics are linear, so CADET's sigma_x(t) = 0.01 t is exact and the design keeps "
                       "x_mean + 0.03 t <= 1/9), the final conditions on the mean, confirmed by 2000 Monte Carlo "
                       "flights of the open-loop control (99.95% kept against Phi(3) = 99.865%). Cost of "
                       "robustness: 0.6859 in control effort (4.6859 against the twin's 4.0000, 17%).",
        "optimum": None, "tolerance": None, "params": BRYSON_DENHAM_ROBUST},
    "betts-shuttle-heat-limit-ocp": {
        "description": "Betts' shuttle maximum crossrange with the heating rate at most 70 BTU/ft^2/s (Betts, "
                       "Practical Methods for Optimal Control, 2nd ed., sec. 6.3), written as ocp expressions as "
                       "betts-shuttle-ocp is, the aerodynamic errors s1, s2 of paper 001 declared at zero. Betts: "
                       "30.6255 deg, tf 2198.67 s; this preset on 100 intervals (the limit held between the nodes "
                       "too): 30.62088 deg, tf 2198.09 s (the reentry kind's node-enforced 30.62788 deg "
                       "overshoots 70 between nodes). Deterministic twin of betts-shuttle-robust-ocp. Tolerance "
                       "0.01 deg.",
        "optimum": 30.6255, "tolerance": 0.01, "params": SHUTTLE_HEAT_LIMITED},
    "betts-shuttle-robust-ocp": {
        "description": "Paper 001 (reentry trajectory robust optimization with CADET, 2020) posed as an ocp: the "
                       "robust_reentry kind's robust-max-crossrange. betts-shuttle-heat-limit-ocp with CD = CD_N "
                       "(1 + s1), CL = CL_N (1 + s2), s1 ~ N(0.01, 0.01^2), s2 ~ N(-0.01, 0.01^2); the mean - 3 "
                       "sigma of the final latitude maximized and the heating limit held at mean + 3 sigma (CADET "
                       "through the expressions), confirmed by 10,000 Monte Carlo flights of the open-loop controls. "
                       "The first design (k = 3) gives mean - 3 sigma = 28.2220 deg (the robust_reentry kind's first "
                       "design: 28.2340 deg, 0.012 deg apart: it holds the robust limit at every RK4 step, this one at "
                       "the nodes with tighten rounds between them; its terminal sigma limits are inactive and not "
                       "posed here); it keeps the limit in 99.42% of the flights, below Phi(3) = 99.865%, so the "
                       "limit's k is raised to 3.576 and the re-solved design (tf 2220.44 s) gives 28.1331 deg, kept "
                       "by 99.95% (the kind: k 3.495, 28.1578 deg, tf 2222.97 s; its Monte Carlo, 10,000 draws too, "
                       "kept 99.54% at k = 3). Monte Carlo mean / sigma of the final latitude 28.810 / 0.258 deg "
                       "against CADET's first-order 28.865 / 0.244 deg. Cost of robustness: 2.488 deg of mean - 3 "
                       "sigma latitude (28.1331 against the twin's 30.6209 deg; the Monte Carlo's mean latitude is "
                       "1.81 deg below the twin's).",
        "optimum": None, "tolerance": None, "params": SHUTTLE_HEAT_LIMITED_ROBUST},
}
