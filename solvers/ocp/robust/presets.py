"""Robust-design presets of the ``ocp`` kind, each with its deterministic twin (the same params without
``uncertainty`` and ``robust``), merged into :data:`solvers.ocp.cases.PRESETS`.  Each description states
the cost of robustness: the robust design's objective against the twin's, on the preset's own grid, as
measured by ``tests/unit/test_ocp_robust_presets.py``.  Standard library only.
"""
from __future__ import annotations

import copy

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
}
