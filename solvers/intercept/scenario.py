"""The long-range interception scenario (paper 003), held once for both methods.

Interceptor and target orbits at the epoch t0 = 0, the interceptor's vehicle data
and the interception time ``tf_s`` (fixed, or free within ``tf_bounds_s``).  The
impulsive method (:mod:`solvers.intercept`) and the finite-thrust method
(:mod:`solvers.intercept.thrust`) both hold one of these; SI units and radians.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.astro.elements import Elements, elements_to_state
from solvers.astro.j2 import AE_EARTH, MU_EARTH
from solvers.constants import G0_MPS2


@dataclass(frozen=True)
class InterceptScenario:
    """Who intercepts whom, with what, and when (SI, radians; epoch t0 = 0)."""

    interceptor_orbit: Elements
    target_orbit: Elements            # circular: argp 0, nu is the argument of latitude
    mass_kg: float                    # initial (wet) mass
    propellant_kg: float              # part of mass_kg
    isp_s: float
    max_thrust_n: float               # finite-thrust method only
    tf_s: float                       # interception time; with free_final_time the first guess
    free_final_time: bool = False     # finite-thrust method only
    tf_bounds_s: tuple[float, float] = (6000.0, 10200.0)
    mu_m3_s2: float = MU_EARTH
    body_radius_m: float = AE_EARTH   # a trajectory below it passes through the planet
    g0_mps2: float = G0_MPS2          # the paper's fuel figures use 9.8

    @property
    def exhaust_speed_mps(self) -> float:
        return self.isp_s * self.g0_mps2

    def initial_states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(r_interceptor_m, v_interceptor_mps, r_target_m, v_target_mps)`` at t0, inertial."""
        ri, vi = elements_to_state(self.mu_m3_s2, self.interceptor_orbit)
        rt, vt = elements_to_state(self.mu_m3_s2, self.target_orbit)
        return ri, vi, rt, vt

    def fuel_kg(self, delta_v_mps):
        """Propellant for ``delta_v_mps`` from the rocket equation (Tsiolkovsky), from mass_kg."""
        return self.mass_kg * (1.0 - np.exp(-np.asarray(delta_v_mps) / self.exhaust_speed_mps))
