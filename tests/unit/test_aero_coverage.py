"""The result says when a flight left its aero data (issue 28 item 4): how far beyond the table's alpha and
Mach breakpoints, or that a polynomial rode an alpha bound; nothing is said where the data covers it."""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from solvers.models import shuttle as sh
from solvers.models.aerodynamics import AeroTable
from solvers.models.aero_coverage import aero_coverage_notes
from solvers.models.atmosphere import Atmosphere

TABLE = AeroTable(alpha_deg=(0.0, 10.0, 20.0, 30.0), mach=(2.0, 5.0, 10.0, 20.0),
                  cl=[[0.1] * 4, [0.3] * 4, [0.5] * 4, [0.7] * 4], cd=[[0.1] * 4, [0.2] * 4, [0.4] * 4, [0.7] * 4])
# a constant speed of sound, so the Mach numbers below are exact: 300 m/s
VEHICLE = dataclasses.replace(sh.SHUTTLE, aero_table=TABLE,
                              atmosphere=Atmosphere(kind="exponential", rho0_kg_m3=1.2, scale_height_m=7000.0,
                                                    sound_speed_mps=300.0))
BOUNDS = (math.radians(-90.0), math.radians(90.0))


def _states(speeds_mps) -> np.ndarray:
    x = np.zeros((6, len(speeds_mps)))
    x[0] = 50000.0
    x[3] = speeds_mps
    return x


def test_a_flight_inside_the_table_says_so():
    notes = aero_coverage_notes(VEHICLE, _states([6000.0, 1500.0]), np.radians([5.0, 25.0]), alpha_bounds_rad=BOUNDS)
    assert notes == ["aero table: the flight stays within its data (alpha 5.00 to 25.00 deg against breakpoints "
                     "0 to 30 deg; Mach 5.00 to 20.00 against 2 to 20)"]


def test_how_far_beyond_the_table_in_alpha_and_mach():
    # alpha to 42.5 deg (12.5 beyond 30), Mach from 7500/300 = 25 (5 beyond 20) down to 300/300 = 1 (1 below 2)
    notes = aero_coverage_notes(VEHICLE, _states([7500.0, 300.0]), np.radians([42.5, 10.0]), alpha_bounds_rad=BOUNDS)
    assert len(notes) == 1 and notes[0].startswith("warning: aero table extrapolated: alpha up to 12.50 deg beyond "
                                                   "the table, Mach up to 5.00 beyond the table"), notes
    assert "held at the edge breakpoints' values" in notes[0]


def test_a_polynomial_on_its_alpha_bound_is_flagged_and_off_it_is_not():
    shuttle = dataclasses.replace(sh.SHUTTLE, aero_table=None)
    x = _states([7000.0, 1000.0])
    assert aero_coverage_notes(shuttle, x, np.radians([17.0, 40.0]), alpha_bounds_rad=BOUNDS) == []
    notes = aero_coverage_notes(shuttle, x, np.radians([17.0, 90.0]), alpha_bounds_rad=BOUNDS)
    assert len(notes) == 1 and "rides the bound bounds.alpha_deg [-90, 90]" in notes[0]
