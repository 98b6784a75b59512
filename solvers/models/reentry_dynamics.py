"""3-DOF point-mass reentry dynamics over a spherical Earth, for numpy and CasADi alike.

Non-rotating equations: Betts, *Practical Methods for Optimal Control*, 2nd ed., sec. 6.3,
eqs. 6.93-6.98.  Rotating Earth (Coriolis and centripetal terms): paper 000 eq. (22), written
here with the heading ``psi`` measured from north (paper 000 measures its heading from east,
``psi_s = 90 deg - psi``), as in Vinh, *Hypersonic and Planetary Entry Flight Mechanics*.

State ``x = (h [m], lon [rad], lat [rad], v [m/s], gamma [rad], psi [rad])``, control
``u = (alpha [rad], bank [rad])``.  ``x`` may be shape (6,) or (6, N) (vectorized over N nodes
or samples) numpy arrays, or CasADi SX/MX of shape (6, 1) or (6, N); ``xp`` is ``numpy`` or
``casadi`` (auto-detected when None).  Aero and heating fits take alpha in degrees; the heating
fit takes slug/ft^3 and ft/s (Betts eq. 6.101) and is converted to W/m^2 here.  A vehicle may
instead carry aerodynamic tables against alpha and Mach (:mod:`solvers.models.aerodynamics`) and
the Sutton-Graves heating correlation (:mod:`solvers.models.heating`); the planet and the
atmosphere are the vehicle's too.
"""
from __future__ import annotations

import numpy as np

from solvers.constants import G0_MPS2
from solvers.models import shuttle as sh
from solvers.models.atmosphere import backend


def _rows(a, n, xp):
    if xp is np:
        a = np.asarray(a, dtype=float) if not isinstance(a, np.ndarray) else a
        return [a[i] for i in range(n)]
    return [a[i, :] for i in range(n)]


def _stack(rows, xp):
    if xp is np:
        return np.stack(np.broadcast_arrays(*rows), axis=0)
    return xp.vertcat(*rows)


def _poly(coeffs, a):
    out = coeffs[-1]
    for c in reversed(coeffs[:-1]):
        out = out * a + c
    return out


def aero(x, u, p, xp=None, *, cd_scale=1.0, cl_scale=1.0):
    """``(rho [kg/m^3], CL, CD)`` at the given states and controls."""
    xp = xp or backend(x, u, cd_scale, cl_scale)
    h = _rows(x, 6, xp)[0]
    alpha = _rows(u, 2, xp)[0]
    a_deg = alpha / sh.DEG
    rho = p.atmosphere.density(h, xp)
    if p.aero_table is not None:
        mach = _rows(x, 6, xp)[3] / p.atmosphere.speed_of_sound(h, xp)
        cl0 = p.aero_table.coefficient("cl", a_deg, mach, xp)
        cd0 = p.aero_table.coefficient("cd", a_deg, mach, xp)
    else:
        cl0, cd0 = _poly(p.cl_coeffs, a_deg), _poly(p.cd_coeffs, a_deg)
    cl = cl0 * p.cl_scale * cl_scale
    cd = cd0 * p.cd_scale * cd_scale
    return rho, cl, cd


def eom(x, u, p, xp=None, *, cd_scale=1.0, cl_scale=1.0):
    """Time derivative of the state (SI/radians per second), same shape as ``x``.

    ``cd_scale``/``cl_scale`` (numbers, arrays over N, or symbols) multiply ``p``'s own scales.
    """
    xp = xp or backend(x, u, cd_scale, cl_scale)
    h, lon, lat, v, gam, psi = _rows(x, 6, xp)
    alpha, bank = _rows(u, 2, xp)
    rho, cl, cd = aero(x, u, p, xp, cd_scale=cd_scale, cl_scale=cl_scale)
    r = p.planet.radius_m + h
    g = p.planet.mu_m3_s2 / r ** 2
    qs = 0.5 * rho * v ** 2 * p.area_m2
    lift = qs * cl
    drag = qs * cd
    m = p.mass_kg
    sg, cg = xp.sin(gam), xp.cos(gam)
    sp, cp = xp.sin(psi), xp.cos(psi)
    sl, cl_ = xp.sin(lat), xp.cos(lat)
    dh = v * sg
    dlon = v * cg * sp / (r * cl_)
    dlat = v * cg * cp / r
    dv = -drag / m - g * sg
    dgam = lift * xp.cos(bank) / (m * v) + cg * (v / r - g / v)
    dpsi = lift * xp.sin(bank) / (m * v * cg) + v * cg * sp * sl / (r * cl_)
    if p.rotating_earth:
        w = p.planet.omega_rad_s
        dv = dv + w ** 2 * r * cl_ * (sg * cl_ - cg * sl * cp)
        dgam = dgam + 2.0 * w * cl_ * sp + w ** 2 * r * cl_ * (cg * cl_ + sg * cp * sl) / v
        dpsi = dpsi - 2.0 * w * (sg / cg * cp * cl_ - sl) + w ** 2 * r * sp * sl * cl_ / (v * cg)
    return _stack([dh, dlon, dlat, dv, dgam, dpsi], xp)


def heat_rate(x, u, p, xp=None):
    """Stagnation heating rate in W/m^2 by the vehicle's model: Sutton-Graves when it has one,
    else Betts' fit (eq. 6.101, BTU/ft^2/s inside)."""
    xp = xp or backend(x, u)
    h, _, _, v, _, _ = _rows(x, 6, xp)
    if p.heating is not None:
        return p.heating.heat_rate(p.atmosphere.density(h, xp), v, p.planet, xp)
    alpha = _rows(u, 2, xp)[0]
    a_deg = alpha / sh.DEG
    rho_e = p.atmosphere.density(h, xp) * sh.KG_M3_TO_SLUG_FT3
    v_e = v / sh.FT_TO_M
    q_btu = _poly(p.heat_coeffs, a_deg) * 17700.0 * xp.sqrt(rho_e) * (1e-4 * v_e) ** 3.07
    return q_btu * sh.BTU_FT2_S_TO_W_M2


def dynamic_pressure(x, p, xp=None):
    """``0.5 rho v^2`` in Pa."""
    xp = xp or backend(x)
    h, _, _, v, _, _ = _rows(x, 6, xp)
    return 0.5 * p.atmosphere.density(h, xp) * v ** 2


def load_factor(x, u, p, xp=None, *, cd_scale=1.0, cl_scale=1.0):
    """Aerodynamic load factor ``sqrt(L^2 + D^2) / (m g0)`` (dimensionless, g0 = 9.80665)."""
    xp = xp or backend(x, u, cd_scale, cl_scale)
    v = _rows(x, 6, xp)[3]
    rho, cl, cd = aero(x, u, p, xp, cd_scale=cd_scale, cl_scale=cl_scale)
    qs = 0.5 * rho * v ** 2 * p.area_m2
    return qs * xp.sqrt(cl ** 2 + cd ** 2) / (p.mass_kg * G0_MPS2)


def stagnation_heat_integrand(x, p, xp=None):
    """Paper 000's heat-load integrand ``sqrt(rho) v^3`` in SI (its case 3/4 objective)."""
    xp = xp or backend(x)
    h, _, _, v, _, _ = _rows(x, 6, xp)
    return xp.sqrt(p.atmosphere.density(h, xp)) * v ** 3
