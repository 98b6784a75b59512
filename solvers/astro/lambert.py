"""Lambert's problem, vectorized: the conic from r1 to r2 in a given time of flight.

Izzo's algorithm (D. Izzo, "Revisiting Lambert's problem", Celest. Mech. Dyn.
Astr. 121, 2015): the problem is reduced to the non-dimensional time of
flight ``T(x)`` on the single parameter ``x`` (eq. 18-20), whose root is found
with third-order Householder iterations (eq. 30) from the initial guesses of
eq. 30/31; velocities are reconstructed with eq. 25.  Near the parabola
(``|x - 1| < 0.01``) ``T(x)`` is evaluated with Battin's hypergeometric series
(eq. 20) because Lancaster's closed form cancels catastrophically there.

All cases of a batch are iterated together with masks (no Python loop over
cases), which is what makes ~10^5-10^6 solves/s possible with numpy alone.

Conventions (as in Izzo/pykep): the transfer is *prograde* when the angular
momentum of the transfer has a positive z component.  For ``revolutions > 0``
two solutions exist when the time of flight exceeds the minimum for that
number of revolutions; ``low_path=True`` selects the one with the larger
``x`` (the right branch of eq. 31), ``low_path=False`` the other, following
poliastro/lamberthub's ``lowpath`` flag.  Where no solution exists the case is
``converged=False`` with NaN velocities.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.astro.batch import broadcast_pair

_BATTIN_BAND = 0.01      # |x - 1| below which Lancaster's form loses digits (pykep's threshold)
_X_TOL_SINGLE = 1e-11    # Householder is third order: a step this small leaves ~1e-16 error
_X_TOL_MULTI = 1e-11
_MAX_ITER = 35
_MAX_ITER_TMIN = 12


@dataclass
class LambertSolution:
    """Departure and arrival velocities (m/s) of each case; NaN where not converged."""

    v1: np.ndarray          # (N, 3) or (3,)
    v2: np.ndarray          # (N, 3) or (3,)
    converged: np.ndarray   # (N,) bool, or 0-d for a single case
    iterations: np.ndarray  # (N,) int, or 0-d for a single case


def _norm(a: np.ndarray) -> np.ndarray:
    # einsum on broadcast (strided) inputs is several times slower than this
    return np.sqrt(a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1] + a[:, 2] * a[:, 2])


def _hyp2f1b(x: np.ndarray) -> np.ndarray:
    """Gauss hypergeometric 2F1(3, 1; 5/2; x) for |x| small (Izzo eq. 20)."""
    res = np.ones_like(x)
    term = np.ones_like(x)
    for k in range(60):
        term = term * (3.0 + k) * (1.0 + k) / (2.5 + k) * x / (k + 1.0)
        res = res + term
        if np.all(np.abs(term) <= 1e-17 * np.abs(res)):
            break
    return res


def _tof(x: np.ndarray, lam: np.ndarray, m: np.ndarray | int) -> np.ndarray:
    """Non-dimensional time of flight T(x) (Izzo eq. 18 with Battin's series near x=1)."""
    lam2 = lam * lam
    e = x * x - 1.0
    rho = np.abs(e)
    z = np.sqrt(1.0 + lam2 * e)
    out = np.empty_like(x)
    near = np.abs(x - 1.0) < _BATTIN_BAND
    far = ~near
    if np.any(far):
        xf, lf, zf, ef = x[far], lam[far], z[far], e[far]
        mf = m[far] if np.ndim(m) else m
        y = np.sqrt(np.abs(ef))
        g = xf * zf - lf * ef
        ell = ef < 0.0
        d = np.empty_like(xf)
        # arccos argument can leave [-1, 1] by rounding only
        d[ell] = (mf[ell] if np.ndim(mf) else mf) * np.pi + np.arccos(np.clip(g[ell], -1.0, 1.0))
        hyp = ~ell
        d[hyp] = np.log(y[hyp] * (zf[hyp] - lf[hyp] * xf[hyp]) + g[hyp])
        out[far] = (xf - lf * zf - d / y) / ef
    if np.any(near):
        xn, ln, zn = x[near], lam[near], z[near]
        mn = m[near] if np.ndim(m) else m
        eta = zn - ln * xn
        s1 = 0.5 * (1.0 - ln - xn * eta)
        q = 4.0 / 3.0 * _hyp2f1b(s1)
        out[near] = (eta ** 3 * q + 4.0 * ln * eta) / 2.0 + mn * np.pi / np.maximum(rho[near], 1e-300) ** 1.5
    return out


def _dtof(x: np.ndarray, t: np.ndarray, lam: np.ndarray):
    """First three derivatives of T(x) (Izzo eq. 22), given T at x."""
    lam2 = lam * lam
    lam3 = lam2 * lam
    umx2 = 1.0 - x * x
    y = np.sqrt(1.0 - lam2 * umx2)
    y2 = y * y
    y3 = y2 * y
    d1 = (3.0 * t * x - 2.0 + 2.0 * lam3 * x / y) / umx2
    d2 = (3.0 * t + 5.0 * x * d1 + 2.0 * (1.0 - lam2) * lam3 / y3) / umx2
    d3 = (7.0 * x * d2 + 8.0 * d1 - 6.0 * (1.0 - lam2) * lam2 * lam3 * x / (y3 * y2)) / umx2
    return d1, d2, d3


def _householder(t_target, x0, lam, m, tol):
    """Third-order Householder iterations on T(x) = T, all cases at once (Izzo eq. 30)."""
    x = x0.copy()
    iters = np.zeros(x.shape, dtype=np.int64)
    active = np.ones(x.shape, dtype=bool)
    idx = np.arange(x.size)
    for _ in range(_MAX_ITER):
        if idx.size == 0:
            break
        xa, la, ta = x[idx], lam[idx], t_target[idx]
        ma = m[idx] if np.ndim(m) else m
        tof = _tof(xa, la, ma)
        d1, d2, d3 = _dtof(xa, tof, la)
        delta = tof - ta
        d1sq = d1 * d1
        xn = xa - delta * (d1sq - delta * d2 / 2.0) / (d1 * (d1sq - delta * d2) + d3 * delta * delta / 6.0)
        x[idx] = xn
        iters[idx] += 1
        done = ~(np.abs(xn - xa) > tol)  # NaN counts as done (and is caught as not converged)
        active[idx[done]] = False
        idx = idx[~done]
    return x, iters, active


def _tmin(lam, m):
    """Minimum non-dimensional time of flight for m revolutions (Halley on dT/dx = 0)."""
    x = np.zeros_like(lam)
    t = np.arccos(lam) + lam * np.sqrt(1.0 - lam * lam) + m * np.pi
    for _ in range(_MAX_ITER_TMIN):
        d1, d2, d3 = _dtof(x, t, lam)
        step = d1 * d2 / (d2 * d2 - d1 * d3 / 2.0)
        step = np.where(d1 != 0.0, step, 0.0)
        x = x - step
        t = _tof(x, lam, m)
        if np.all(np.abs(step) < 1e-13):
            break
    return t


def lambert(mu: float, r1, r2, tof, *, revolutions: int = 0, prograde: bool = True,
            low_path: bool = True) -> LambertSolution:
    """Solve Lambert's problem for one case or a batch.

    ``r1``, ``r2``: (3,) or (N, 3) positions in m; ``tof``: scalar or (N,) in s
    (broadcast against the positions); ``mu`` in m^3/s^2.  The leading shape of
    the input is kept: (3,) in gives (3,) velocities out.
    """
    r1b, r2b, tofb, single = broadcast_pair(r1, r2, tof)
    n = tofb.shape[0]
    m = int(revolutions)
    if m < 0:
        raise ValueError("revolutions must be >= 0")

    c = r2b - r1b
    cn = _norm(c)
    r1n = _norm(r1b)
    r2n = _norm(r2b)
    s = 0.5 * (r1n + r2n + cn)
    ir1 = r1b / r1n[:, None]
    ir2 = r2b / r2n[:, None]
    ih = np.cross(ir1, ir2)
    ihn = _norm(ih)
    # r1 and r2 collinear: the transfer plane is undefined (and cn = 0 makes lambda = 1)
    valid = (ihn > 1e-12) & (cn > 0.0) & (tofb > 0.0) & np.isfinite(tofb) & (r1n > 0) & (r2n > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        ih = ih / ihn[:, None]
        lam = np.sqrt(np.clip(1.0 - cn / s, 0.0, 1.0))
        flip = ih[:, 2] < 0.0
        # Izzo: the short way is the transfer whose angular momentum has +z
        if not prograde:
            flip = ~flip
        lam = np.where(flip, -lam, lam)
        it1 = np.cross(ih, ir1)
        it2 = np.cross(ih, ir2)
        sign = np.where(flip, -1.0, 1.0)[:, None]
        it1 = it1 * sign
        it2 = it2 * sign
        t = np.sqrt(2.0 * mu / s ** 3) * tofb

    x = np.full(n, np.nan)
    iters = np.zeros(n, dtype=np.int64)
    conv = np.zeros(n, dtype=bool)
    idx = np.flatnonzero(valid)
    if idx.size:
        lv, tv = lam[idx], t[idx]
        lam2 = lv * lv
        if m == 0:
            t00 = np.arccos(lv) + lv * np.sqrt(1.0 - lam2)
            t1 = 2.0 / 3.0 * (1.0 - lam2 * lv)
            with np.errstate(invalid="ignore", divide="ignore"):
                x0 = np.where(
                    tv >= t00, (t00 / tv) ** (2.0 / 3.0) - 1.0,
                    np.where(tv < t1,
                             2.5 * t1 / tv * (t1 - tv) / (1.0 - lam2 * lam2 * lv) + 1.0,
                             (tv / t00) ** (np.log(2.0) / np.log(t1 / t00)) - 1.0))
            ok = np.ones(idx.size, dtype=bool)
            tol = _X_TOL_SINGLE
        else:
            t0m = np.arccos(lv) + lv * np.sqrt(1.0 - lam2) + m * np.pi
            ok = np.ones(idx.size, dtype=bool)
            below = tv < t0m
            if np.any(below):
                ok[below] = tv[below] >= _tmin(lv[below], m)
            with np.errstate(invalid="ignore", divide="ignore"):
                a = ((m * np.pi + np.pi) / (8.0 * tv)) ** (2.0 / 3.0)
                x0l = (a - 1.0) / (a + 1.0)
                b = ((8.0 * tv) / (m * np.pi)) ** (2.0 / 3.0)
                x0r = (b - 1.0) / (b + 1.0)
            x0 = np.maximum(x0l, x0r) if low_path else np.minimum(x0l, x0r)
            tol = _X_TOL_MULTI
        sub = idx[ok]
        if sub.size:
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                xs, its, still = _householder(tv[ok], x0[ok], lv[ok], m, tol)
            x[sub] = xs
            iters[sub] = its
            conv[sub] = ~still & np.isfinite(xs)
            if m > 0:
                conv[sub] &= np.abs(xs) < 1.0  # multi-rev solutions are ellipses

    with np.errstate(invalid="ignore", divide="ignore"):
        gamma = np.sqrt(mu * s / 2.0)
        rho = (r1n - r2n) / cn
        sigma = np.sqrt(np.clip(1.0 - rho * rho, 0.0, None))
        y = np.sqrt(1.0 - lam * lam + lam * lam * x * x)
        vr1 = gamma * ((lam * y - x) - rho * (lam * y + x)) / r1n
        vr2 = -gamma * ((lam * y - x) + rho * (lam * y + x)) / r2n
        vt = gamma * sigma * (y + lam * x)
        v1 = vr1[:, None] * ir1 + (vt / r1n)[:, None] * it1
        v2 = vr2[:, None] * ir2 + (vt / r2n)[:, None] * it2
    conv &= np.isfinite(v1).all(axis=1) & np.isfinite(v2).all(axis=1)
    v1[~conv] = np.nan
    v2[~conv] = np.nan
    if single:
        return LambertSolution(v1=v1[0], v2=v2[0], converged=conv[0], iterations=iters[0])
    return LambertSolution(v1=v1, v2=v2, converged=conv, iterations=iters)
