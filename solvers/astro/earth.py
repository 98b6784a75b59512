"""Earth's constants, defined once (SI): gravitational parameter, J2, equatorial radius,
flattening.  Numpy-free on purpose, so the API edge can read its defaults from here
without loading the numerics; :mod:`solvers.astro.j2` re-exports them."""
from __future__ import annotations

MU_EARTH = 3.986004418e14        # m^3/s^2, paper 002 / WGS-84 (= 398600.4418 km^3/s^2)
J2_EARTH = 1.08263e-3            # paper 002
AE_EARTH = 6378137.0             # m, WGS-84 semi-major axis
WGS84_FLATTENING = 1.0 / 298.257223563
