"""Atmosphere density models for reentry dynamics, in SI, usable on numpy and CasADi.

* :class:`Atmosphere` ``kind="exponential"``: ``rho = rho0 exp(-h / hr)``, the model of the
  Betts shuttle benchmark (Betts, *Practical Methods for Optimal Control*, 2nd ed., sec. 6.3:
  ``rho0 = 0.002378 slug/ft^3``, ``hr = 23800 ft``).
* ``kind="us1976"``: the U.S. Standard Atmosphere 1976 below 86 km (seven geopotential layers,
  hydrostatic with linear temperature per layer), continued above its top by an exponential
  whose scale height matches the top layer, so that density stays smooth and positive.
* ``kind="table"``: density against altitude (Mars, or a user's model), interpolated by a cubic
  B-spline in **log-density** (:mod:`solvers.models.tables`), so the density is smooth, positive
  and has exact derivatives; above and below the table the log-density goes on linearly with the
  spline's end slope (an exponential with the local scale height).

Speed of sound (for the Mach number of aerodynamic tables), :meth:`Atmosphere.speed_of_sound`:
US 1976 from its temperature (``sqrt(1.4 R T)``); a table from its optional ``sound_speeds_mps``
column (B-spline, clamped at the ends); otherwise the constant ``sound_speed_mps`` (default the
sea-level standard 340.294 m/s).  The choice is the atmosphere's, because the temperature is.

Both accept ``h`` as a float, a numpy array, or a CasADi SX/MX expression; ``xp`` is the
module (``numpy`` or ``casadi``) whose elementary functions to use (auto-detected if None).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from solvers.constants import G0_MPS2
from solvers.models import tables

# U.S. Standard Atmosphere 1976, layers below 86 km geometric (84.852 km geopotential).
_R_AIR = 287.05287           # J/(kg K)
_RE_GEOPOT = 6356766.0       # m, Earth radius used for geopotential altitude
_GAMMA_AIR = 1.4             # ratio of specific heats of air (US 1976 speed of sound)
_H_BASE = np.array([0.0, 11000.0, 20000.0, 32000.0, 47000.0, 51000.0, 71000.0, 84852.0])
_LAPSE = np.array([-6.5e-3, 0.0, 1.0e-3, 2.8e-3, 0.0, -2.8e-3, -2.0e-3])


def _layer_bases():
    t, p = [288.15], [101325.0]
    for i, lapse in enumerate(_LAPSE):
        dh = _H_BASE[i + 1] - _H_BASE[i]
        tb, pb = t[-1], p[-1]
        if lapse == 0.0:
            p.append(pb * np.exp(-G0_MPS2 * dh / (_R_AIR * tb)))
        else:
            p.append(pb * ((tb + lapse * dh) / tb) ** (-G0_MPS2 / (_R_AIR * lapse)))
        t.append(tb + lapse * dh)
    return np.array(t), np.array(p)


_T_BASE, _P_BASE = _layer_bases()


def backend(*args):
    """The array module for these arguments: casadi if any is symbolic, else numpy."""
    for a in args:
        if type(a).__module__.startswith("casadi"):
            import casadi
            return casadi
    return np


def where(cond, a, b, xp):
    if xp is np:
        return np.where(cond, a, b)
    return xp.if_else(cond, a, b)


@dataclass(frozen=True)
class Atmosphere:
    """Density model.  ``rho0_kg_m3``/``scale_height_m``: ``exponential`` only; ``altitudes_m``,
    ``densities_kg_m3`` (and optionally ``sound_speeds_mps``, same length): ``table`` only;
    ``sound_speed_mps``: the constant speed of sound where the model has no temperature.

    The defaults are a generic sea-level exponential Earth atmosphere; the Betts
    benchmark's values are :data:`solvers.models.shuttle.BETTS_ATMOSPHERE`.
    """

    kind: str = "exponential"
    rho0_kg_m3: float = 1.225
    scale_height_m: float = 7200.0
    altitudes_m: tuple = ()
    densities_kg_m3: tuple = ()
    sound_speeds_mps: tuple = ()
    sound_speed_mps: float = 340.294

    def __post_init__(self):
        if self.kind not in ("exponential", "us1976", "table"):
            raise ValueError(f"unknown atmosphere kind {self.kind!r}")
        # tuples (hashable: the atmosphere keys the solver cache), also after a JSON round trip
        for name in ("altitudes_m", "densities_kg_m3", "sound_speeds_mps"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        if self.kind == "table":
            tables.check_breakpoints(self.altitudes_m, "altitudes_m", minimum=4)
            rho = np.asarray(self.densities_kg_m3)
            if rho.size != len(self.altitudes_m) or not np.all(rho > 0) or not np.all(np.isfinite(rho)):
                raise ValueError("densities_kg_m3 must be positive, one per altitude")
            a = np.asarray(self.sound_speeds_mps)
            if a.size and (a.size != rho.size or not np.all(a > 0)):
                raise ValueError("sound_speeds_mps must be positive, one per altitude (or empty)")

    def density(self, h, xp=None):
        """Density in kg/m^3 at geometric altitude ``h`` (m)."""
        xp = xp or backend(h)
        if self.kind == "exponential":
            return self.rho0_kg_m3 * xp.exp(-h / self.scale_height_m)
        if self.kind == "us1976":
            return _us1976_density(h, xp)
        return xp.exp(self._log_density(h, xp))

    def _log_density(self, h, xp):
        fn, s_lo, s_hi = _log_density_table(self.altitudes_m, self.densities_kg_m3)
        lo, hi = self.altitudes_m[0], self.altitudes_m[-1]
        hc = tables.clamp(h, lo, hi, xp)
        inside = tables.evaluate(fn, [hc], xp=xp)
        # beyond the table: linear in log-density with the end slope (C1 at the ends)
        return inside + s_lo * xp.fmin(h - lo, 0.0) + s_hi * xp.fmax(h - hi, 0.0)

    def speed_of_sound(self, h, xp=None):
        """Speed of sound in m/s at altitude ``h`` (m): see the module docstring for the choice."""
        xp = xp or backend(h)
        if self.kind == "us1976":
            return xp.sqrt(_GAMMA_AIR * _R_AIR * _us1976_temperature(h, xp))
        if self.kind == "table" and self.sound_speeds_mps:
            grid = (self.altitudes_m,)
            hc = tables.clamp(h, grid[0][0], grid[0][-1], xp)
            return tables.evaluate(tables.spline(grid, self.sound_speeds_mps), [hc], xp=xp)
        return self.sound_speed_mps + 0.0 * h


@lru_cache(maxsize=32)
def _log_density_table(altitudes: tuple, densities: tuple):
    """The log-density spline and its slopes at both ends (numbers: they extend it linearly)."""
    import casadi as ca
    fn = tables.spline((altitudes,), tuple(float(v) for v in np.log(densities)))
    x = ca.SX.sym("h")
    d = ca.Function("d", [x], [ca.jacobian(fn(x), x)])
    return fn, float(d(altitudes[0])), float(d(altitudes[-1]))


def _us1976_temperature(h, xp):
    """US 1976 temperature (K), linear per layer, isothermal above 84.852 km geopotential."""
    hg = _RE_GEOPOT * h / (_RE_GEOPOT + h)
    t = _T_BASE[7] + 0.0 * hg
    for i in range(6, -1, -1):
        lo, hi = _H_BASE[i], _H_BASE[i + 1]
        layer = _T_BASE[i] + _LAPSE[i] * (xp.fmin(xp.fmax(hg, lo), hi) - lo)
        t = where(hg < hi, layer, t, xp)
    # below sea level the lowest layer's lapse rate goes on
    return where(hg < 0.0, _T_BASE[0] + _LAPSE[0] * xp.fmax(hg, -5000.0), t, xp)


def _layer_density(hg, i, xp):
    tb, pb, lapse = _T_BASE[i], _P_BASE[i], _LAPSE[i] if i < len(_LAPSE) else 0.0
    # Clamp to the layer so the branch not selected by ``where`` never takes a negative
    # temperature to a fractional power (NaN in its value or derivative).
    lo = _H_BASE[i]
    hi = _H_BASE[i + 1] if i + 1 < len(_H_BASE) else None
    hg = xp.fmax(hg, lo) if hi is None else xp.fmin(xp.fmax(hg, lo), hi)
    dh = hg - lo
    if lapse == 0.0:
        p = pb * xp.exp(-G0_MPS2 * dh / (_R_AIR * tb))
        t = tb
    else:
        t = tb + lapse * dh
        p = pb * (t / tb) ** (-G0_MPS2 / (_R_AIR * lapse))
    return p / (_R_AIR * t)


def _us1976_density(h, xp):
    hg = _RE_GEOPOT * h / (_RE_GEOPOT + h)
    # Above the last layer base: isothermal continuation (exponential with the local scale
    # height), which keeps the density and its slope continuous at 84.852 km.
    rho = _layer_density(hg, 7, xp)
    # below 0 m the lowest layer is extrapolated rather than clamped
    bottom = _layer_density_unclamped(hg, xp)
    for i in range(6, -1, -1):
        rho = where(hg < _H_BASE[i + 1], _layer_density(hg, i, xp), rho, xp)
    return where(hg < 0.0, bottom, rho, xp)


def _layer_density_unclamped(hg, xp):
    t = _T_BASE[0] + _LAPSE[0] * xp.fmin(xp.fmax(hg, -5000.0), 0.0)
    p = _P_BASE[0] * (t / _T_BASE[0]) ** (-G0_MPS2 / (_R_AIR * _LAPSE[0]))
    return p / (_R_AIR * t)
