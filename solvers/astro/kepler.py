"""Two-body (Keplerian) propagation with universal variables, vectorized.

Kepler's equation in the universal anomaly chi (Curtis, "Orbital Mechanics
for Engineering Students", sec. 3.7, eq. 3.49; Vallado, "Fundamentals of
Astrodynamics and Applications", 4th ed., alg. 8) is solved with Newton's
method for all states and times at once; the state follows from the Lagrange
coefficients f, g, fdot, gdot (Curtis eq. 3.69).  Valid for ellipses,
parabolas and hyperbolas.
"""
from __future__ import annotations

import numpy as np

from solvers.astro.batch import broadcast_pair

_SERIES_Z = 0.1   # |z| below which the Stumpff closed forms cancel; use their series
_MAX_ITER = 60
_TOL = 1e-14


def stumpff(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stumpff functions C(z), S(z) (Curtis eq. 3.52-3.53), with series near z = 0."""
    z = np.asarray(z, dtype=float)
    c = np.empty_like(z)
    s = np.empty_like(z)
    pos = z > _SERIES_Z
    neg = z < -_SERIES_Z
    mid = ~(pos | neg)
    if np.any(pos):
        sz = np.sqrt(z[pos])
        # 1 - cos cancels near sz = 2 pi (multi-revolution Lambert); the half-angle form does not
        c[pos] = 2.0 * np.sin(0.5 * sz) ** 2 / z[pos]
        s[pos] = (sz - np.sin(sz)) / sz ** 3
    if np.any(neg):
        sz = np.sqrt(-z[neg])
        c[neg] = (np.cosh(sz) - 1.0) / -z[neg]
        s[neg] = (np.sinh(sz) - sz) / sz ** 3
    if np.any(mid):
        zm = z[mid]
        # terms (-z)^k/(2k+2)! and (-z)^k/(2k+3)!; 7 terms leave < 1e-18 at |z| = 0.1
        cc = np.zeros_like(zm)
        ss = np.zeros_like(zm)
        term_c, term_s = 0.5, 1.0 / 6.0
        zp = np.ones_like(zm)
        for k in range(7):
            cc += term_c * zp
            ss += term_s * zp
            zp = zp * -zm
            term_c /= (2 * k + 3) * (2 * k + 4)
            term_s /= (2 * k + 4) * (2 * k + 5)
        c[mid] = cc
        s[mid] = ss
    return c, s


def propagate(mu: float, r0, v0, dt) -> tuple[np.ndarray, np.ndarray]:
    """Propagate states (r0, v0) by dt under two-body gravity.

    ``r0``, ``v0``: (3,) or (N, 3) in m and m/s; ``dt``: scalar or (N,) in s
    (negative allowed); they broadcast against each other, so one state can be
    propagated to many times or many states by one time.  Returns (r, v) with
    the broadcast leading shape ((3,) for a single state and time).
    """
    r0b, v0b, dtb, single = broadcast_pair(r0, v0, dt)
    n = dtb.shape[0]

    rn = np.sqrt(np.einsum("ij,ij->i", r0b, r0b))
    vr = np.einsum("ij,ij->i", r0b, v0b) / rn
    v2 = np.einsum("ij,ij->i", v0b, v0b)
    alpha = 2.0 / rn - v2 / mu       # 1/a
    sqmu = np.sqrt(mu)

    # Whole periods add nothing on an ellipse but cost iterations and digits; on
    # [0, period) the root is bracketed by chi in [0, 2 pi sqrt(a)].
    ell = alpha > 1e-12
    dtr = dtb.copy()
    lo = np.full(n, -np.inf)
    hi = np.full(n, np.inf)
    if np.any(ell):
        period = 2.0 * np.pi / np.sqrt(mu * alpha[ell] ** 3)
        dtr[ell] = np.mod(dtb[ell], period)
        lo[ell] = 0.0
        hi[ell] = 2.0 * np.pi / np.sqrt(alpha[ell])

    chi = np.empty(n)
    chi[ell] = sqmu * alpha[ell] * dtr[ell]
    hyp = alpha < -1e-12
    if np.any(hyp):
        a = 1.0 / alpha[hyp]
        sgn = np.sign(dtr[hyp])
        sgn = np.where(sgn == 0.0, 1.0, sgn)
        with np.errstate(invalid="ignore", divide="ignore"):
            arg = (-2.0 * mu * alpha[hyp] * dtr[hyp]
                   / (rn[hyp] * vr[hyp] + sgn * np.sqrt(-mu * a) * (1.0 - rn[hyp] * alpha[hyp])))
            guess = sgn * np.sqrt(-a) * np.log(arg)
        # Vallado's guess is for long arcs: for short ones the log can have the wrong sign
        # (chi must share the sign of dt) and then Laguerre runs into cosh overflow.
        fallback = sqmu * dtr[hyp] / rn[hyp]
        chi[hyp] = np.where(np.isfinite(guess) & (guess * sgn > 0), guess, fallback)
    par = ~(ell | hyp)
    if np.any(par):
        chi[par] = sqmu * dtr[par] / rn[par]

    # Laguerre-Conway iterations on F(chi) = sqrt(mu) dt (Curtis eq. 3.49): plain
    # Newton overshoots on eccentric orbits; Laguerre converges from any start on
    # ellipses.  F' = r(chi) > 0, so F is monotone and a sign change tightens the
    # bracket, which is bisected if an iterate leaves it.
    sig0 = rn * vr / sqmu
    k = 5.0
    idx = np.arange(n)
    for _ in range(_MAX_ITER):
        if idx.size == 0:
            break
        x = chi[idx]
        al, r0i, s0 = alpha[idx], rn[idx], sig0[idx]
        z = al * x * x
        c, s = stumpff(z)
        x2 = x * x
        f = s0 * x2 * c + (1.0 - al * r0i) * x2 * x * s + r0i * x - sqmu * dtr[idx]
        fp = s0 * x * (1.0 - z * s) + (1.0 - al * r0i) * x2 * c + r0i
        fpp = s0 * (1.0 - z * c) + (1.0 - al * r0i) * x * (1.0 - z * s)
        lo_i = np.where(f < 0.0, np.maximum(lo[idx], x), lo[idx])
        hi_i = np.where(f > 0.0, np.minimum(hi[idx], x), hi[idx])
        lo[idx], hi[idx] = lo_i, hi_i
        disc = np.sqrt(np.abs((k - 1.0) ** 2 * fp * fp - k * (k - 1.0) * f * fpp))
        xn = x - k * f / (fp + np.sign(fp) * disc)
        outside = ~((xn >= lo_i) & (xn <= hi_i)) & np.isfinite(lo_i) & np.isfinite(hi_i) & (f != 0.0)
        with np.errstate(invalid="ignore"):  # inf - inf on unbracketed (hyperbolic) rows, not selected
            xn = np.where(outside, 0.5 * (lo_i + hi_i), xn)
        chi[idx] = xn
        done = (np.abs(xn - x) <= _TOL * np.maximum(1.0, np.abs(x))) | (f == 0.0)
        idx = idx[~done]

    z = alpha * chi * chi
    c, s = stumpff(z)
    f = 1.0 - chi * chi / rn * c
    g = dtr - chi ** 3 * s / sqmu
    r = f[:, None] * r0b + g[:, None] * v0b
    rnew = np.sqrt(np.einsum("ij,ij->i", r, r))
    fdot = sqmu / (rnew * rn) * (alpha * chi ** 3 * s - chi)
    gdot = 1.0 - chi * chi / rnew * c
    v = fdot[:, None] * r0b + gdot[:, None] * v0b
    if single:
        return r[0], v[0]
    return r, v
