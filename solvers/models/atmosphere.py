"""Atmosphere density models for reentry dynamics, in SI, usable on numpy and CasADi.

* :class:`Atmosphere` ``kind="exponential"``: ``rho = rho0 exp(-h / hr)``, the model of the
  Betts shuttle benchmark (Betts, *Practical Methods for Optimal Control*, 2nd ed., sec. 6.3:
  ``rho0 = 0.002378 slug/ft^3``, ``hr = 23800 ft``).
* ``kind="us1976"``: the U.S. Standard Atmosphere 1976 below 86 km (seven geopotential layers,
  hydrostatic with linear temperature per layer), continued above its top by an exponential
  whose scale height matches the top layer, so that density stays smooth and positive.

Both accept ``h`` as a float, a numpy array, or a CasADi SX/MX expression; ``xp`` is the
module (``numpy`` or ``casadi``) whose elementary functions to use (auto-detected if None).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.constants import G0_MPS2

# U.S. Standard Atmosphere 1976, layers below 86 km geometric (84.852 km geopotential).
_R_AIR = 287.05287           # J/(kg K)
_RE_GEOPOT = 6356766.0       # m, Earth radius used for geopotential altitude
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
    """Density model; ``rho0_kg_m3``/``scale_height_m`` only used by ``exponential``.

    The defaults are a generic sea-level exponential Earth atmosphere; the Betts
    benchmark's values are :data:`solvers.models.shuttle.BETTS_ATMOSPHERE`.
    """

    kind: str = "exponential"
    rho0_kg_m3: float = 1.225
    scale_height_m: float = 7200.0

    def density(self, h, xp=None):
        """Density in kg/m^3 at geometric altitude ``h`` (m)."""
        xp = xp or backend(h)
        if self.kind == "exponential":
            return self.rho0_kg_m3 * xp.exp(-h / self.scale_height_m)
        if self.kind == "us1976":
            return _us1976_density(h, xp)
        raise ValueError(f"unknown atmosphere kind {self.kind!r}")


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
