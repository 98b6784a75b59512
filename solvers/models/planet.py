"""Planets of the reentry dynamics: gravitational parameter, radius, rotation, J2, and the gas
constant of the Sutton-Graves heating correlation.

The reentry equations (:mod:`solvers.models.reentry_dynamics`) use a spherical planet with
central gravity ``mu / r^2`` (as Betts and paper 000 do) and the rotation rate when
``rotating_earth`` is set; ``j2`` is carried as data for models that use it and is **not** used
by the reentry dynamics.  Earth as Betts poses it: :data:`solvers.models.shuttle.EARTH_BETTS`.

Mars (:data:`MARS`): NASA GSFC Mars Fact Sheet (D. R. Williams, nssdc.gsfc.nasa.gov/planetary/
factsheet/marsfact.html): GM 42828.3e9 m^3/s^2, equatorial radius 3396.2 km, sidereal rotation
period 24.6229 h, J2 1960.45e-6; the MSL entry interface is quoted at radius 3522.2 km, i.e.
126 km above this radius.  Sutton-Graves constants: 1.7415e-4 (Earth), 1.9027e-4 (Mars) in SI.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

SUTTON_GRAVES_K_EARTH = 1.7415e-4    # kg^0.5 / m (q in W/m^2)
SUTTON_GRAVES_K_MARS = 1.9027e-4


@dataclass(frozen=True)
class Planet:
    mu_m3_s2: float
    radius_m: float
    omega_rad_s: float = 7.2921159e-5
    j2: float = 0.0
    sutton_graves_k: float = SUTTON_GRAVES_K_EARTH
    name: str = "earth"


MARS = Planet(mu_m3_s2=4.28283e13, radius_m=3396.2e3, omega_rad_s=2.0 * math.pi / (24.6229 * 3600.0),
              j2=1960.45e-6, sutton_graves_k=SUTTON_GRAVES_K_MARS, name="mars")
