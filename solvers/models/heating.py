"""Stagnation-point heating correlations a vehicle may carry (besides Betts' shuttle fit).

Sutton-Graves (K. Sutton and R. A. Graves, "A General Stagnation-Point Convective-Heating
Equation for Arbitrary Gas Mixtures", NASA TR R-376, 1971): ``q = k sqrt(rho / r_n) v^3`` in
W/m^2 with ``rho`` in kg/m^3, the nose radius ``r_n`` in m and ``v`` in m/s; ``k`` depends on the
gas: 1.7415e-4 kg^0.5/m for Earth air, 1.9027e-4 for the Mars atmosphere (the planet's
``sutton_graves_k``, :mod:`solvers.models.planet`), unless the vehicle gives its own.

The Betts fit (Betts, *Practical Methods for Optimal Control*, eq. 6.101) stays in
:mod:`solvers.models.reentry_dynamics`; a :class:`solvers.models.shuttle.Vehicle` with
``heating=None`` uses it with its ``heat_coeffs``.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SuttonGraves:
    """``q = k sqrt(rho / r_n) v^3``; ``k=None``: the planet's constant.  In a built NLP both
    numbers may be CasADi symbols (they are parameters, not structure)."""

    nose_radius_m: float
    k: float | None = None

    def __post_init__(self):
        if not type(self.nose_radius_m).__module__.startswith("casadi") and not self.nose_radius_m > 0:
            raise ValueError("nose_radius_m must be positive")

    def heat_rate(self, rho, v, planet, xp):
        """Stagnation heating rate in W/m^2."""
        k = planet.sutton_graves_k if self.k is None else self.k
        return k * xp.sqrt(rho / self.nose_radius_m) * v ** 3
