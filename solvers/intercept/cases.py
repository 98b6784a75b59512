"""Paper 003's interception case, the one place presets, tests and benchmarks read it from.

The orbits and vehicle exactly as printed (spec ``shared/specs/intercept.md``), with
standard gravity 9.80665 m/s^2 (the paper's own figures use 9.8), and the reference
numbers our tests and benchmarks compare against.
"""
from __future__ import annotations

import math
from dataclasses import replace

from solvers.astro.elements import Elements
from solvers.intercept.scenario import InterceptScenario

PAPER_003 = InterceptScenario(
    interceptor_orbit=Elements(a=16678.137e3, e=0.2, i=math.radians(28.5), raan=0.0, argp=0.0,
                               nu=math.radians(1.54)),
    target_orbit=Elements(a=6878.137e3, e=0.0, i=math.radians(30.0), raan=0.0, argp=0.0, nu=math.radians(2.05)),
    mass_kg=500.0, propellant_kg=400.0, isp_s=300.0, max_thrust_n=2000.0, tf_s=8080.5,
)

# Single impulse with the printed elements: one minimum (prograde, 0 revolutions).
IMPULSIVE_DELTA_V_MPS = 2302.48
IMPULSIVE_T_MAN_S = 3142.5
# Finite thrust: the spec's careful reimplementation (200-interval multiple shooting).
REFERENCE_FUEL_KG = 270.84
# Ours, switch times solved for exactly: the same to 1e-5 kg on a mesh of twice the nodes; the
# spec's 270.84 kg is about 0.6 kg low (its discretization).
CONVERGED_FUEL_KG = 271.418


def is_paper_003(scenario: InterceptScenario) -> bool:
    """Whether ``scenario`` is paper 003's own case (orbits, vehicle, interception time, mu), so
    that the paper's figures may be quoted beside its answer; the standard gravity of the
    rocket equation and the free-final-time settings may differ."""
    same = replace(scenario, g0_mps2=PAPER_003.g0_mps2, free_final_time=False, tf_bounds_s=PAPER_003.tf_bounds_s,
                   body_radius_m=PAPER_003.body_radius_m)
    try:
        return bool(same == PAPER_003)
    except ValueError:   # elements given as arrays: not the paper's scalar case
        return False
