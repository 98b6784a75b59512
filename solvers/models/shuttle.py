"""Space Shuttle orbiter reentry data of the Betts benchmark, in SI, and the unit conversions.

Source: J. T. Betts, *Practical Methods for Optimal Control and Estimation Using Nonlinear
Programming*, 2nd ed., SIAM 2010, sec. 6.3 "Space Shuttle Reentry Trajectory" (eqs. 6.93-6.101);
the same data drive the reentry examples of GPOPS-II, PSOPT, Dymos and ICLOCS.  Betts gives
everything in English units; this module is the one place where they are converted to SI, and
where the fits that *want* English units (aero in alpha degrees, heating in slug/ft^3 and ft/s,
answering BTU/ft^2/s) are wrapped.

Paper 000 (Qu Xiangju, direct multiple shooting for Shuttle reentry, 1991) used vehicle data
from a report we do not have; its cases are posed here on this vehicle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from solvers.models.aerodynamics import AeroTable
from solvers.models.atmosphere import Atmosphere
from solvers.models.heating import SuttonGraves
from solvers.models.planet import Planet

# --- unit conversions (exact where defined exactly) -------------------------------------
FT_TO_M = 0.3048
FT2_TO_M2 = FT_TO_M ** 2
FT3_TO_M3 = FT_TO_M ** 3
SLUG_TO_KG = 14.593902937206364              # lbf s^2/ft
SLUG_FT3_TO_KG_M3 = SLUG_TO_KG / FT3_TO_M3   # 515.3788...
KG_M3_TO_SLUG_FT3 = 1.0 / SLUG_FT3_TO_KG_M3
BTU_FT2_S_TO_W_M2 = 11356.5                  # value fixed by the spec: 70 BTU/ft^2/s = 794955 W/m^2
DEG = math.pi / 180.0


@dataclass(frozen=True)
class Vehicle:
    """Point-mass lifting vehicle: mass, reference area, aerodynamics, heating model, and the
    atmosphere and planet it flies in.

    Aerodynamics: ``aero_table`` (:class:`solvers.models.aerodynamics.AeroTable`, CL/CD against
    alpha and Mach) when given, else the polynomials in alpha **degrees**, lowest order first:
    ``CL = sum cl[k] a^k``.  Heating: ``heating`` (:class:`solvers.models.heating.SuttonGraves`)
    when given, else Betts' fit: ``heat_coeffs`` multiply ``17700 sqrt(rho[slug/ft^3])
    (1e-4 v[ft/s])^3.07`` (eq. 6.101) and give BTU/ft^2/s, converted to W/m^2 by
    :func:`solvers.models.reentry_dynamics.heat_rate`.  ``cd_scale``/``cl_scale`` multiply the
    coefficients of either aerodynamic model (robust kind: ``CD = CD_N (1 + s1)``).
    Fields may hold CasADi symbols, so a built NLP can take the vehicle as parameters.
    """

    mass_kg: float
    area_m2: float
    cl_coeffs: tuple = (-0.20704, 0.029244)
    cd_coeffs: tuple = (0.07854, -0.61592e-2, 0.621408e-3)
    heat_coeffs: tuple = (1.0672181, -0.19213774e-1, 0.21286289e-3, -0.10117249e-5)
    atmosphere: Atmosphere = field(default_factory=Atmosphere)
    planet: Planet = field(default_factory=lambda: EARTH_BETTS)
    rotating_earth: bool = False
    cd_scale: float = 1.0
    cl_scale: float = 1.0
    aero_table: AeroTable | None = None
    heating: SuttonGraves | None = None


ReentryModel = Vehicle
"""Alias: the dynamics' parameter object (vehicle + atmosphere + planet + flags)."""

# Betts' spherical, non-rotating Earth (the rotation rate is used only with rotating_earth).
EARTH_BETTS: Planet = Planet(mu_m3_s2=0.14076539e17 * FT3_TO_M3, radius_m=20902900.0 * FT_TO_M, name="earth")
BETTS_ATMOSPHERE = Atmosphere(kind="exponential", rho0_kg_m3=0.002378 * SLUG_FT3_TO_KG_M3,
                              scale_height_m=23800.0 * FT_TO_M)
# Betts: weight 203000 lb with g0 = 32.174 ft/s^2, i.e. mass in slugs; S = 2690 ft^2.
SHUTTLE = Vehicle(mass_kg=203000.0 / 32.174 * SLUG_TO_KG, area_m2=2690.0 * FT2_TO_M2,
                  atmosphere=BETTS_ATMOSPHERE, planet=EARTH_BETTS)

# State x = (h [m], lon [rad], lat [rad], v [m/s], gamma [rad], psi [rad]); psi from north.
BETTS_INITIAL_STATE = (260000.0 * FT_TO_M, 0.0, 0.0, 25600.0 * FT_TO_M, -1.0 * DEG, 90.0 * DEG)
BETTS_TERMINAL = {"altitude_m": 80000.0 * FT_TO_M, "speed_mps": 2500.0 * FT_TO_M,
                  "flight_path_rad": -5.0 * DEG}
BETTS_ALPHA_BOUNDS_RAD = (-90.0 * DEG, 90.0 * DEG)
BETTS_BANK_BOUNDS_RAD = (-90.0 * DEG, 1.0 * DEG)
BETTS_HEAT_LIMIT_W_M2 = 70.0 * BTU_FT2_S_TO_W_M2
# Kept away from the equations' singularities (Betts): v >= 100 ft/s, |gamma|, |lat| <= 89 deg.
BETTS_MIN_SPEED_MPS = 100.0 * FT_TO_M
SINGULARITY_MARGIN_RAD = 89.0 * DEG

# Paper 000's cases end at 130000 ft with alpha <= 40 deg.
PAPER000_TERMINAL_ALTITUDE_M = 39624.0
PAPER000_ALPHA_MAX_RAD = 40.0 * DEG
