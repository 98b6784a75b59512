"""Nonlinear relative motion of a thrusting spacecraft about a circular target.

Frame (Hill / RSW of the target): origin at the target, ``x`` radial (target
position direction), ``y`` along-track (completes the right-handed triad, along
the target velocity for a circular orbit), ``z`` orbit normal (target angular
momentum).  The frame rotates at the target's mean motion ``n``.

Equations (paper 003 sec. 1.1, the "nonlinear C-W equations"; exact two-body
relative motion for a circular reference orbit, no linearisation):

    x'' - 2 n y' - n^2 (a + x) = -mu (a + x) / rc^3 + Tx / m
    y'' + 2 n x'       - n^2 y = -mu y / rc^3       + Ty / m
    z''                        = -mu z / rc^3       + Tz / m
    m'                         = -|T| / (Isp g0),    rc = |(a + x, y, z)|

Nondimensionalisation (paper 003 sec. 1.2): length by the target radius ``a``,
time by ``1/n``, mass by the initial mass ``m0``; then ``mu = n = 1``.

Controls inside the NLP are the throttle ``u in [0, 1]`` and a direction ``d``
with ``|d| <= 1`` (thrust ``Tmax u d``, mass flow ``Tmax u / c``): both bounds
are smooth, the throttle takes the bang-bang structure on its simple bounds,
and ``|d| = 1`` holds at any optimum with ``u > 0`` (a shorter ``d`` wastes fuel).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

STATE_NAMES = ("x", "y", "z", "vx", "vy", "vz", "m")
CONTROL_NAMES = ("u", "dx", "dy", "dz")
NX, NU = 7, 4


@dataclass(frozen=True)
class HillScales:
    """Units of the nondimensional problem (SI)."""

    length_m: float      # target orbit radius a
    time_s: float        # 1 / n
    mass_kg: float       # initial mass m0

    @classmethod
    def of(cls, *, mu_m3_s2: float, radius_m: float, mass_kg: float) -> "HillScales":
        return cls(radius_m, float(np.sqrt(radius_m**3 / mu_m3_s2)), mass_kg)

    @property
    def speed_mps(self) -> float:
        return self.length_m / self.time_s

    @property
    def accel_mps2(self) -> float:
        return self.length_m / self.time_s**2

    @property
    def force_n(self) -> float:
        return self.mass_kg * self.accel_mps2


def dynamics_casadi(x, u, tmax, c):
    """Nondimensional state rate (7) for state ``x`` (7) and control ``u`` (4).

    ``tmax`` is the thrust limit and ``c`` the exhaust speed, both
    nondimensional (may be CasADi symbols so one build serves any engine).
    """
    X = 1.0 + x[0]
    rc2 = X**2 + x[1] ** 2 + x[2] ** 2
    g = rc2 ** (-1.5)
    acc = tmax * u[0] / x[6]
    return ca.vertcat(
        x[3], x[4], x[5],
        2.0 * x[4] + X - g * X + acc * u[1],
        -2.0 * x[3] + x[1] - g * x[1] + acc * u[2],
        -g * x[2] + acc * u[3],
        -tmax * u[0] / c,
    )


def dynamics_numpy(x: np.ndarray, thrust: np.ndarray, mdot: np.ndarray) -> np.ndarray:
    """Vectorised nondimensional state rate: ``x`` (7, K), thrust (3, K), mass flow (K)."""
    X = 1.0 + x[0]
    g = (X**2 + x[1] ** 2 + x[2] ** 2) ** (-1.5)
    a = thrust / x[6]
    return np.stack([
        x[3], x[4], x[5],
        2.0 * x[4] + X - g * X + a[0],
        -2.0 * x[3] + x[1] - g * x[1] + a[1],
        -g * x[2] + a[2],
        -mdot,
    ])


def hill_axes(r_t: np.ndarray, v_t: np.ndarray) -> np.ndarray:
    """Rows x, y, z of the Hill frame in inertial axes; vectorised: (..., 3) -> (..., 3, 3)."""
    xh = r_t / np.linalg.norm(r_t, axis=-1, keepdims=True)
    h = np.cross(r_t, v_t)
    zh = h / np.linalg.norm(h, axis=-1, keepdims=True)
    yh = np.cross(zh, xh)
    return np.stack([xh, yh, zh], axis=-2)


def inertial_to_hill(*, r_i: np.ndarray, v_i: np.ndarray, r_t: np.ndarray,
                     v_t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Relative position and velocity (seen from the rotating frame) in Hill axes, SI."""
    R = hill_axes(r_t, v_t)
    omega = np.cross(r_t, v_t) / np.sum(r_t * r_t, axis=-1, keepdims=True)
    dr = r_i - r_t
    dv = v_i - v_t - np.cross(omega, dr)
    return np.einsum("...ij,...j->...i", R, dr), np.einsum("...ij,...j->...i", R, dv)


def hill_to_inertial(*, rho: np.ndarray, rho_dot: np.ndarray, r_t: np.ndarray,
                     v_t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`inertial_to_hill`."""
    R = hill_axes(r_t, v_t)
    omega = np.cross(r_t, v_t) / np.sum(r_t * r_t, axis=-1, keepdims=True)
    dr = np.einsum("...ji,...j->...i", R, rho)
    dv = np.einsum("...ji,...j->...i", R, rho_dot) + np.cross(omega, dr)
    return r_t + dr, v_t + dv


def circular_state(*, r0: np.ndarray, v0: np.ndarray, mu: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact position and velocity (len(t), 3) on a circular orbit at times ``t`` after (r0, v0)."""
    t = np.atleast_1d(np.asarray(t, float))
    a = np.linalg.norm(r0)
    n = np.sqrt(mu / a**3)
    e1 = r0 / a
    e2 = v0 / np.linalg.norm(v0)
    th = n * t[:, None]
    r = a * (np.cos(th) * e1 + np.sin(th) * e2)
    v = a * n * (-np.sin(th) * e1 + np.cos(th) * e2)
    return r, v
