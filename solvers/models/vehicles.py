"""Named vehicles, planets and atmospheres: the data a job may name instead of giving its own.

* ``shuttle``: the Betts Space Shuttle orbiter (:mod:`solvers.models.shuttle`): polynomial aero in
  alpha, Betts' heating fit, Betts' exponential atmosphere over his spherical Earth.
* ``msl``: the Mars Science Laboratory entry capsule.  Published data: entry mass 3257 kg, 4.5 m
  diameter (reference area 15.9 m^2), nose radius 1.125 m, trim near alpha -16 deg with hypersonic
  L/D about 0.24 and CD about 1.45-1.68 (Way et al., "Mars Science Laboratory: Entry, Descent,
  and Landing System Performance", IEEE Aerospace Conference 2007; Mendeck & Craig, "Entry
  Guidance for the 2011 Mars Science Laboratory Mission", AIAA 2011-6639).  The MSL aerodynamic
  database is not public in tabular form: :data:`MSL_AERO` is a smooth table *built to these
  published trim values* (see :func:`msl_aero_table`), not the database.  Heating:
  Sutton-Graves with the Mars constant and the 1.125 m nose radius.
* Mars: :data:`solvers.models.planet.MARS`; atmosphere :data:`MARS_ATMOSPHERE`, a log-density
  table of the NASA Glenn Research Center Mars model (grc.nasa.gov/www/k-12/airplane/atmosmrm.html,
  fitted to Mars Global Surveyor data 1996): ``p = 0.699 exp(-9e-5 h)`` kPa, ``T = -31 -
  0.000998 h`` degC below 7 km and ``-23.4 - 0.00222 h`` above, ``rho = p / (0.1921 T[K])``.
  That fit's temperature reaches 0 K at 112 km; here it is held at 140 K above 49.7 km (the upper
  atmosphere is near 130-150 K), our continuation, so the table reaches the 125 km entry
  interface.  Speed of sound column: ``sqrt(1.29 * 192.1 T)`` (CO2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from solvers.models import shuttle as sh
from solvers.models.aerodynamics import AeroTable
from solvers.models.atmosphere import Atmosphere
from solvers.models.heating import SuttonGraves
from solvers.models.planet import MARS, Planet

PLANETS: dict[str, Planet] = {"earth": sh.EARTH_BETTS, "mars": MARS}

_MARS_R = 192.1            # J/(kg K), the Glenn model's 0.1921 kJ/(kg K)
_MARS_GAMMA = 1.29         # CO2
_MARS_T_FLOOR_K = 140.0


def mars_glenn_profile(h):
    """``(rho [kg/m^3], T [K])`` of the Glenn Mars model (with the 140 K floor) at ``h`` (m)."""
    h = np.asarray(h, float)
    t_c = np.where(h < 7000.0, -31.0 - 0.000998 * h, -23.4 - 0.00222 * h)
    t_k = np.maximum(t_c + 273.1, _MARS_T_FLOOR_K)
    p_kpa = 0.699 * np.exp(-0.00009 * h)
    return p_kpa / (0.1921 * t_k), t_k


def _mars_atmosphere() -> Atmosphere:
    h = np.arange(0.0, 130001.0, 5000.0)
    rho, t = mars_glenn_profile(h)
    return Atmosphere(kind="table", altitudes_m=tuple(h), densities_kg_m3=tuple(rho),
                      sound_speeds_mps=tuple(np.sqrt(_MARS_GAMMA * _MARS_R * t)),
                      sound_speed_mps=float(np.sqrt(_MARS_GAMMA * _MARS_R * t[0])))


MARS_ATMOSPHERE = _mars_atmosphere()
ATMOSPHERES: dict[str, Atmosphere] = {"betts": sh.BETTS_ATMOSPHERE, "us1976": Atmosphere(kind="us1976"),
                                      "mars": MARS_ATMOSPHERE}

MSL_TRIM_ALPHA_DEG = -16.0
MSL_MASS_KG = 3257.0
MSL_DIAMETER_M = 4.5
MSL_NOSE_RADIUS_M = 1.125


def msl_aero_table() -> AeroTable:
    """CL, CD of a 70-deg sphere-cone capsule against alpha (deg) and Mach, built to MSL's trim.

    Body axes: axial force ``CA(M)`` independent of alpha and normal force ``CN = k CA alpha``
    (alpha in rad); wind axes ``CD = CA cos a + CN sin a``, ``CL = CN cos a - CA sin a``.
    ``k = 0.1565`` puts L/D at 0.240 at alpha -16 deg; ``CA(M)`` puts CD at trim from 1.45
    (Mach 1.5) to 1.65 (hypersonic), the published range.
    """
    alpha = np.arange(-24.0, -7.9, 2.0)
    mach = np.array([1.5, 3.0, 5.0, 10.0, 25.0])
    cd_trim = np.array([1.45, 1.52, 1.58, 1.64, 1.65])
    a0 = math.radians(MSL_TRIM_ALPHA_DEG)
    k = 0.1565
    ca_m = cd_trim / (math.cos(a0) + k * a0 * math.sin(a0))   # CA giving cd_trim at trim
    a = np.radians(alpha)[:, None]
    ca_ = ca_m[None, :] * np.ones_like(a)
    cn = k * ca_ * a
    return AeroTable(alpha_deg=tuple(alpha), mach=tuple(mach), cl=cn * np.cos(a) - ca_ * np.sin(a),
                     cd=ca_ * np.cos(a) + cn * np.sin(a))


MSL_AERO = msl_aero_table()
MSL = sh.Vehicle(mass_kg=MSL_MASS_KG, area_m2=math.pi * (MSL_DIAMETER_M / 2) ** 2, aero_table=MSL_AERO,
                 heating=SuttonGraves(nose_radius_m=MSL_NOSE_RADIUS_M), atmosphere=MARS_ATMOSPHERE,
                 planet=MARS)


@dataclass(frozen=True)
class VehiclePreset:
    """A named vehicle with the planet and atmosphere it flies in (inside ``vehicle``)."""

    name: str
    description: str
    vehicle: sh.Vehicle


VEHICLES: dict[str, VehiclePreset] = {p.name: p for p in (
    VehiclePreset("shuttle", "Space Shuttle orbiter of the Betts benchmark (Betts, Practical Methods for "
                  "Optimal Control, 2nd ed., sec. 6.3): 92079 kg, 249.9 m^2, CL and CD polynomials in "
                  "alpha, Betts' heating fit (BTU/ft^2/s, converted), Betts' exponential atmosphere "
                  "(rho0 0.002378 slug/ft^3, scale height 23800 ft) over his spherical Earth.", sh.SHUTTLE),
    VehiclePreset("msl", "Mars Science Laboratory entry capsule (Way et al. 2007, 'Mars Science "
                  "Laboratory: Entry, Descent, and Landing System Performance', IEEE Aerospace Conf.; "
                  "Mendeck & Craig 2011, AIAA 2011-6639): 3257 kg at entry, 4.5 m diameter (15.9 m^2), "
                  "nose radius 1.125 m, Sutton-Graves heating with the Mars constant 1.9027e-4. Aero: a "
                  "smooth table against alpha (-24..-8 deg) and Mach (1.5..25) built to the published "
                  "trim (alpha -16 deg, L/D 0.24, CD 1.45 at Mach 1.5 to 1.65 hypersonic), not the MSL "
                  "aerodynamic database. Mars: GSFC fact sheet constants; atmosphere: log-density table "
                  "of the NASA Glenn Mars model (temperature held at 140 K above 49.7 km, our "
                  "continuation).", MSL),
)}


def vehicle_preset(name: str) -> VehiclePreset:
    """The named vehicle; ``KeyError`` naming the known ones otherwise."""
    try:
        return VEHICLES[name]
    except KeyError:
        raise KeyError(f"unknown vehicle {name!r}; known: {sorted(VEHICLES)}") from None
