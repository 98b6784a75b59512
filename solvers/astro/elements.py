"""Classical orbital elements <-> Cartesian state (inertial frame), vectorized.

Perifocal-to-inertial rotation 3-1-3 (RAAN, inclination, argument of perigee)
as in Curtis, "Orbital Mechanics for Engineering Students", algorithms 4.2
(state from elements) and 4.5 (elements from state).  SI units and radians.
Circular orbits use argument of perigee 0 and the true anomaly measured from
the ascending node (the argument of latitude); equatorial orbits measure from
the x axis.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Elements:
    """Classical elements; every field may be a scalar or an (N,) array."""

    a: float | np.ndarray        # semi-major axis, m (negative for hyperbolas)
    e: float | np.ndarray        # eccentricity
    i: float | np.ndarray        # inclination, rad
    raan: float | np.ndarray     # right ascension of the ascending node, rad
    argp: float | np.ndarray     # argument of perigee, rad
    nu: float | np.ndarray       # true anomaly, rad


def elements_to_state(mu: float, el: Elements) -> tuple[np.ndarray, np.ndarray]:
    """(r, v) in m, m/s; (3,) for scalar elements, (N, 3) for arrays."""
    a, e, i, raan, argp, nu = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in
                                                    (el.a, el.e, el.i, el.raan, el.argp, el.nu)))
    p = a * (1.0 - e * e)
    r_pf = p / (1.0 + e * np.cos(nu))
    sq = np.sqrt(mu / p)
    rp = np.stack([r_pf * np.cos(nu), r_pf * np.sin(nu), np.zeros_like(nu)], axis=-1)
    vp = np.stack([-sq * np.sin(nu), sq * (e + np.cos(nu)), np.zeros_like(nu)], axis=-1)
    rot = _perifocal_to_inertial(i, raan, argp)
    r = np.einsum("...ij,...j->...i", rot, rp)
    v = np.einsum("...ij,...j->...i", rot, vp)
    return r, v


def _perifocal_to_inertial(i, raan, argp) -> np.ndarray:
    co, so = np.cos(raan), np.sin(raan)
    cw, sw = np.cos(argp), np.sin(argp)
    ci, si = np.cos(i), np.sin(i)
    return np.stack([
        np.stack([co * cw - so * sw * ci, -co * sw - so * cw * ci, so * si], axis=-1),
        np.stack([so * cw + co * sw * ci, -so * sw + co * cw * ci, -co * si], axis=-1),
        np.stack([sw * si, cw * si, ci], axis=-1),
    ], axis=-2)


def state_to_elements(mu: float, r, v, *, tol: float = 1e-10) -> Elements:
    """Classical elements of (r, v); (3,) gives scalars, (N, 3) gives (N,) arrays."""
    r = np.asarray(r, dtype=float)
    v = np.asarray(v, dtype=float)
    rn = np.linalg.norm(r, axis=-1)
    vn2 = np.einsum("...i,...i->...", v, v)
    vr = np.einsum("...i,...i->...", r, v) / rn
    h = np.cross(r, v)
    hn = np.linalg.norm(h, axis=-1)
    i = np.arccos(np.clip(h[..., 2] / hn, -1.0, 1.0))
    node = np.cross(np.array([0.0, 0.0, 1.0]), h)
    nn = np.linalg.norm(node, axis=-1)
    ev = ((vn2 - mu / rn)[..., None] * r - (rn * vr)[..., None] * v) / mu
    e = np.linalg.norm(ev, axis=-1)
    a = 1.0 / (2.0 / rn - vn2 / mu)

    equatorial = nn < tol * hn
    circular = e < tol
    # reference direction in the orbit plane: the node, or x for equatorial orbits
    ref = np.where(equatorial[..., None], np.array([1.0, 0.0, 0.0]),
                   node / np.where(nn > 0, nn, 1.0)[..., None])
    raan = np.where(equatorial, 0.0, _wrap(np.arctan2(node[..., 1], node[..., 0])))

    def angle(frm, to):
        # signed angle in the orbit plane, positive along the motion
        cos_ = np.einsum("...i,...i->...", frm, to)
        sin_ = np.einsum("...i,...i->...", np.cross(frm, to), h) / hn
        return _wrap(np.arctan2(sin_, cos_))

    eu = ev / np.where(e > 0, e, 1.0)[..., None]
    ru = r / rn[..., None]
    argp = np.where(circular, 0.0, angle(ref, eu))
    nu = np.where(circular, angle(ref, ru), angle(eu, ru))
    return Elements(a=a, e=e, i=i, raan=raan, argp=argp, nu=nu)


def _wrap(angle):
    """Angle in [0, 2 pi): np.mod of a tiny negative number rounds up to 2 pi itself."""
    out = np.mod(angle, 2 * np.pi)
    return np.where(out >= 2 * np.pi, 0.0, out)
