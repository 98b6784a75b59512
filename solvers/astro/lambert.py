"""Lambert's problem, vectorized: the conic from r1 to r2 in a given time of flight.

Izzo's algorithm (D. Izzo, "Revisiting Lambert's problem", Celest. Mech. Dyn.
Astr. 121, 2015): the problem is reduced to the non-dimensional time of
flight ``T(x)`` on the single parameter ``x`` (eq. 18-20), whose root is found
with third-order Householder iterations (eq. 30); velocities are reconstructed
with eq. 25.  Near the parabola (``|x - 1| < 0.01``) ``T(x)`` is evaluated with
Battin's hypergeometric series (eq. 20) because Lancaster's closed form cancels
catastrophically there.

Initial guesses: for zero revolutions Izzo's eq. 30.  For ``m > 0`` revolutions
not eq. 31 (whose guesses are 0.07-0.5 from the root, three Householder steps
and more), but the tof inversion of ``T = (m pi + F(x)) / u^3`` (``u^2 = 1 - x^2``,
F the bounded part of eq. 18) with ``F/u^3`` frozen at its limit on the branch's
asymptote, 2/3 (1 - lam^3) as x -> 1; on the left branch, one further
correction by the series of ``F/u^3``.  Where the time of flight is below T(0),
near the minimum time, from the two roots of ``T_min + T'' (x - x_min)^2 / 2``,
the minimum being needed there anyway to decide whether a solution exists.
These are within ~1e-2 of the root (median 4e-3): two Householder steps for 90%
of the one-revolution cases.  The minimum time is found by Halley from the root
of the linearized ``dT/dx = 0`` (two steps for most cases, four before).

The batch is solved by one loop compiled with numba (``cache=True``: compiled
once per machine, then loaded in ~0.3 s): each case costs under 300
nanoseconds, 3.8 million solves/s on one core with zero revolutions and 3.7
million with one (batches of 10,000; best CPU time on a loaded machine, by
``benchmarks/lambert.py``): 2.9x lamberthub's izzo2015 with zero revolutions
called from a numba loop, and 3.1x it on the same one-revolution cases,
measured in the same run.  The iteration stops one step early once it
is in its order-4 regime (see ``_X_EARLY``).  :func:`arc_min_radius` gives the
smallest radius along the arc flown (periapsis or an end point), after the
solve.  Strict IEEE arithmetic (no ``fastmath``): each case gives the same bits
wherever it sits in a batch; velocities agree with the numpy version to 3e-10
m/s, and the multi-revolution ones with lamberthub's to 2e-14 of the speed.

Conventions (as in Izzo/pykep): the transfer is *prograde* when the angular
momentum of the transfer has a positive z component.  For ``revolutions > 0``
two solutions exist when the time of flight exceeds the minimum for that
number of revolutions; ``low_path=True`` selects the one with the larger
``x`` (the right branch), ``low_path=False`` the other, following
poliastro/lamberthub's ``lowpath`` flag.  Where no solution exists the case is
``converged=False`` with NaN velocities.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from solvers.astro.batch import broadcast_pair

_BATTIN_BAND = 0.01      # |x - 1| below which Lancaster's form loses digits (pykep's threshold)
_X_TOL = 1e-11           # a step this small ends the iteration in any case
# The Householder step with T''' converges with order 4: once a step is below 1e-5 and
# 1000x smaller than the one before (so the iteration is in its fast regime, not creeping to a
# double root), the new x is within ~1e-16 and the next step would only confirm it.  This saves
# 0.8 of the 2.8 iterations of an average zero-revolution case; velocities move by <= 2e-13 relative.
_X_EARLY = 1e-5
_EARLY_RATIO = 1e-3
_MAX_ITER = 35
_MAX_ITER_TMIN = 12
# error_model="numpy": a division by zero gives inf/NaN (caught as not converged), not an exception.
# No fastmath: with it LLVM vectorizes across cases and a case's last bits then depend on where it
# sits in the batch (and on memory alignment), which made NSGA-II fronts differ from run to run.


@dataclass
class LambertSolution:
    """Departure and arrival velocities (m/s) of each case; NaN where not converged."""

    v1: np.ndarray          # (N, 3) or (3,)
    v2: np.ndarray          # (N, 3) or (3,)
    converged: np.ndarray   # (N,) bool, or 0-d for a single case
    iterations: np.ndarray  # (N,) int, or 0-d for a single case


@njit(cache=True, error_model="numpy")
def _hyp2f1b(x):
    """Gauss hypergeometric 2F1(3, 1; 5/2; x) for |x| small (Izzo eq. 20)."""
    res = 1.0
    term = 1.0
    for k in range(60):
        term = term * (3.0 + k) * (1.0 + k) / (2.5 + k) * x / (k + 1.0)
        res += term
        if abs(term) <= 1e-17 * abs(res):
            break
    return res


@njit(cache=True, error_model="numpy")
def _tof(x, lam, m):
    """Non-dimensional time of flight T(x) (Izzo eq. 18 with Battin's series near x=1)."""
    return _tof_z(x, lam, m, math.sqrt(1.0 + lam * lam * (x * x - 1.0)))


@njit(cache=True, error_model="numpy")
def _tof_z(x, lam, m, z):
    """T(x) given ``z = sqrt(1 + lam^2 (x^2 - 1))``, which the derivatives share (one sqrt less)."""
    e = x * x - 1.0
    if abs(x - 1.0) < _BATTIN_BAND:
        eta = z - lam * x
        q = 4.0 / 3.0 * _hyp2f1b(0.5 * (1.0 - lam - x * eta))
        return (eta * eta * eta * q + 4.0 * lam * eta) / 2.0 + m * math.pi / max(abs(e), 1e-300) ** 1.5
    y = math.sqrt(abs(e))
    g = x * z - lam * e
    if e < 0.0:
        d = m * math.pi + math.acos(min(1.0, max(-1.0, g)))  # the argument leaves [-1, 1] by rounding only
    else:
        d = math.log(y * (z - lam * x) + g)
    return (x - lam * z - d / y) / e


@njit(cache=True, error_model="numpy")
def _dtof_z(x, t, lam, y):
    """First three derivatives of T(x) (Izzo eq. 22), given T at x and ``y = sqrt(1 - lam^2 (1 - x^2))``."""
    lam2 = lam * lam
    lam3 = lam2 * lam
    # two reciprocals instead of six divisions (a division costs several multiplications)
    iu = 1.0 / (1.0 - x * x)
    iy = 1.0 / y
    iy2 = iy * iy
    iy3 = iy2 * iy
    d1 = (3.0 * t * x - 2.0 + 2.0 * lam3 * x * iy) * iu
    d2 = (3.0 * t + 5.0 * x * d1 + 2.0 * (1.0 - lam2) * lam3 * iy3) * iu
    d3 = (7.0 * x * d2 + 8.0 * d1 - 6.0 * (1.0 - lam2) * lam2 * lam3 * x * (iy3 * iy2)) * iu
    return d1, d2, d3


@njit(cache=True, error_model="numpy")
def _dtof(x, t, lam):
    """First three derivatives of T(x) (Izzo eq. 22), given T at x."""
    return _dtof_z(x, t, lam, math.sqrt(1.0 - lam * lam * (1.0 - x * x)))


@njit(cache=True, error_model="numpy")
def _householder(t, x, lam, m):
    """Third-order Householder iterations on T(x) = t (Izzo eq. 30): (x, iterations, converged).

    T and its derivatives share one square root (``z``) and one reciprocal (``iu`` =
    1/(1 - x^2)), written out here rather than through ``_tof_z``/``_dtof_z``: two of the five
    divisions of a step go, both on its critical path (8% of a batch's time).  The iteration
    ends when a step is below ``_X_TOL``, or below ``_X_EARLY`` in the fast regime (see there).
    """
    lam2 = lam * lam
    lam3 = lam2 * lam
    prev = math.inf
    for it in range(1, _MAX_ITER + 1):
        xx = x * x
        e = xx - 1.0
        z = math.sqrt(1.0 + lam2 * e)
        iu = 1.0 / (1.0 - xx)
        iy = 1.0 / z
        if abs(x - 1.0) < _BATTIN_BAND:
            tof = _tof_z(x, lam, m, z)
        else:
            y = math.sqrt(abs(e))
            g = x * z - lam * e
            if e < 0.0:
                d = m * math.pi + math.acos(min(1.0, max(-1.0, g)))  # the argument leaves [-1, 1] by rounding only
            else:
                d = math.log(y * (z - lam * x) + g)
            # (x - lam z - d / y) / e, with 1/e = -iu and 1/y = y |iu| (y^2 = |e|): no division
            tof = (d * y * abs(iu) - x + lam * z) * iu
        iy2 = iy * iy
        iy3 = iy2 * iy
        d1 = (3.0 * tof * x - 2.0 + 2.0 * lam3 * x * iy) * iu
        d2 = (3.0 * tof + 5.0 * x * d1 + 2.0 * (1.0 - lam2) * lam3 * iy3) * iu
        d3 = (7.0 * x * d2 + 8.0 * d1 - 6.0 * (1.0 - lam2) * lam2 * lam3 * x * (iy3 * iy2)) * iu
        delta = tof - t
        d1sq = d1 * d1
        xn = x - delta * (d1sq - delta * d2 / 2.0) / (d1 * (d1sq - delta * d2) + d3 * delta * delta / 6.0)
        step = abs(xn - x)
        if not step > _X_TOL:  # NaN ends the loop too, and is caught as not converged
            return xn, it, math.isfinite(xn)
        if step < _X_EARLY and step < _EARLY_RATIO * prev:
            return xn, it, math.isfinite(xn)
        prev = step
        x = xn
    return x, _MAX_ITER, False


@njit(cache=True, error_model="numpy")
def _tmin(lam, m, t0m):
    """Minimum non-dimensional time of flight for m revolutions, by Halley on dT/dx = 0:
    ``(T_min, x_min, T'')``, T'' at the last iterate but one (for the initial guesses near T_min).

    ``t0m`` is T(0).  The start is the root of the first-order model of dT/dx = 0 about x = 0,
    ``3 T x - 2 + 2 lam^3 x / z = 0`` with T and z frozen at x = 0 (the lam^3 term only where it
    pulls the root toward 0, as it does for lam -> 1): within ~1e-2 of x_min for most lam, where
    x = 0 was 0.15/m away and, for lam near -1, sent the iteration to a wrong point.
    """
    x = 2.0 / (3.0 * t0m + max(0.0, 2.0 * lam * lam * lam / math.sqrt(1.0 - lam * lam)))
    t = _tof(x, lam, m)
    d2 = 1.0
    prev = 1.0
    for _ in range(_MAX_ITER_TMIN):
        d1, d2, d3 = _dtof(x, t, lam)
        step = d1 * d2 / (d2 * d2 - d1 * d3 / 2.0) if d1 != 0.0 else 0.0
        x -= step
        t = _tof(x, lam, m)
        s = abs(step)
        # T is stationary here, so an x within 1e-7 gives T to ~1e-14, enough to decide whether a
        # time of flight is feasible.  Halley converges cubically: a step below 1e-3 |x| that is
        # also small against the one before (s^3 < 1e-14 prev^2, the fast regime) leaves x within
        # ~1e-14 |x| and ends the iteration a step earlier (scaled by |x|: x_min -> 0 as lam -> 1).
        if not s > 1e-7 or not (s > 1e-3 * abs(x) or s * s * s > 1e-14 * prev * prev):
            break
        prev = s
    return t, x, d2


@njit(cache=True, error_model="numpy")
def _phi(s2):
    """(asin(s) - s sqrt(1 - s^2)) / s^3 by its series in s^2 to s^6 (2/3 2F1(1/2, 3/2; 5/2; s^2)).

    With ``u^2 = 1 - x^2`` the bounded part of T (eq. 18) is ``F(x) = u^3 (phi(u^2) - lam^3
    phi(lam^2 u^2))`` for x >= 0 and ``pi - u^3 (phi(u^2) + lam^3 phi(lam^2 u^2))`` for x <= 0;
    the truncation (0.13 low at u^2 = 0.9) only costs a little of an initial guess's accuracy.
    """
    return 2.0 / 3.0 + s2 * (0.2 + s2 * (3.0 / 28.0 + s2 * (5.0 / 72.0)))


@njit(cache=True, error_model="numpy")
def _solve(mu, r1, r2, tof, m, prograde, low_path, v1, v2, iters):
    """Every case of the batch; fills v1, v2 (NaN where unsolved) and iters, returns converged."""
    n = r1.shape[0]
    conv = np.zeros(n, np.bool_)
    for k in range(n):
        v1[k, :] = np.nan
        v2[k, :] = np.nan
        iters[k] = 0
        c0, c1, c2 = r2[k, 0] - r1[k, 0], r2[k, 1] - r1[k, 1], r2[k, 2] - r1[k, 2]
        cn = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        r1n = math.sqrt(r1[k, 0] ** 2 + r1[k, 1] ** 2 + r1[k, 2] ** 2)
        r2n = math.sqrt(r2[k, 0] ** 2 + r2[k, 1] ** 2 + r2[k, 2] ** 2)
        if not (r1n > 0.0 and r2n > 0.0 and cn > 0.0 and tof[k] > 0.0 and math.isfinite(tof[k])):
            continue
        # reciprocals once: a division costs several multiplications (x * (1/r) is within an ulp of x / r)
        ir1, ir2 = 1.0 / r1n, 1.0 / r2n
        a0, a1, a2 = r1[k, 0] * ir1, r1[k, 1] * ir1, r1[k, 2] * ir1
        b0, b1, b2 = r2[k, 0] * ir2, r2[k, 1] * ir2, r2[k, 2] * ir2
        h0, h1, h2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        hn = math.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
        if not hn > 1e-12:  # r1 and r2 collinear: the transfer plane is undefined
            continue
        ihn = 1.0 / hn
        h0, h1, h2 = h0 * ihn, h1 * ihn, h2 * ihn
        s = 0.5 * (r1n + r2n + cn)
        lam = math.sqrt(min(1.0, max(0.0, 1.0 - cn / s)))
        # Izzo: the short way is the transfer whose angular momentum has +z
        flip = (h2 < 0.0) == prograde
        sg = -1.0 if flip else 1.0
        if flip:
            lam = -lam
        t = math.sqrt(2.0 * mu / (s * s * s)) * tof[k]
        lam2 = lam * lam
        if m == 0:
            t00 = math.acos(lam) + lam * math.sqrt(1.0 - lam2)
            t1 = 2.0 / 3.0 * (1.0 - lam2 * lam)
            if t >= t00:
                x0 = (t00 / t) ** (2.0 / 3.0) - 1.0
            elif t < t1:
                x0 = 2.5 * t1 / t * (t1 - t) / (1.0 - lam2 * lam2 * lam) + 1.0
            else:
                x0 = (t / t00) ** (math.log(2.0) / math.log(t1 / t00)) - 1.0
        else:
            t0m = math.acos(lam) + lam * math.sqrt(1.0 - lam2) + m * math.pi   # T(0)
            if t < t0m:
                # near T_min, where T(x) ~ T_min + T'' (x - x_min)^2 / 2: the two roots either side
                tm, xm, d2 = _tmin(lam, m, t0m)
                if t < tm:
                    continue  # shorter than the minimum time for m revolutions: no solution
                dx = math.sqrt(2.0 * (t - tm) / d2)
                x0 = xm + dx if low_path else xm - dx
            elif low_path:
                # T = (m pi + F(x)) / u^3 with u = sqrt(1 - x^2) and F/u^3 -> 2/3 (1 - lam^3) as x -> 1:
                # with F/u^3 frozen at that limit, u^2 = (m pi / (T - 2/3 (1 - lam^3)))^(2/3).  (The
                # correction of the left branch saves only 0.08 steps here and costs more than that.)
                u2 = (m * math.pi / (t - 2.0 / 3.0 * (1.0 - lam2 * lam))) ** (2.0 / 3.0)
                x0 = math.sqrt(1.0 - min(u2, 1.0))
            else:
                # the left branch, x <= 0 here: T = ((m + 1) pi - G(x)) / u^3 where G/u^3 = phi(u^2) +
                # lam^3 phi(lam^2 u^2) grows from 2/3 (1 + lam^3) at u = 0 (x = -1) to pi - T(0) + m pi
                # at u = 1.  Frozen at u = 0 it gives u2; one correction with the series of phi at
                # u2 (r^(2/3) by its series in d, |d| < 0.3) takes the guess from ~5e-2 to ~1e-2 of x.
                hlim = 2.0 / 3.0 * (1.0 + lam2 * lam)
                u2 = min(1.0, ((m + 1) * math.pi / (t + hlim)) ** (2.0 / 3.0))
                hh = _phi(u2) + lam2 * lam * _phi(lam2 * u2)
                d = (hh - hlim) / (t + hh)
                u2 *= 1.0 - d * (2.0 / 3.0 + d * (1.0 / 9.0 + d * (4.0 / 81.0)))
                x0 = -math.sqrt(1.0 - min(u2, 1.0))
        x, it, ok = _householder(t, x0, lam, m)
        iters[k] = it
        if not ok or (m > 0 and not abs(x) < 1.0):  # multi-revolution solutions are ellipses
            continue
        gamma = math.sqrt(mu * s / 2.0)
        rho = (r1n - r2n) / cn
        sigma = math.sqrt(max(0.0, 1.0 - rho * rho))
        y = math.sqrt(1.0 - lam2 + lam2 * x * x)
        vr1 = gamma * ((lam * y - x) - rho * (lam * y + x)) * ir1
        vr2 = -gamma * ((lam * y - x) + rho * (lam * y + x)) * ir2
        vt1 = gamma * sigma * (y + lam * x) * ir1 * sg
        vt2 = gamma * sigma * (y + lam * x) * ir2 * sg
        # tangential unit vectors: h x r_hat (sign-flipped with the transfer's direction)
        u0, u1, u2 = vr1 * a0 + vt1 * (h1 * a2 - h2 * a1), vr1 * a1 + vt1 * (h2 * a0 - h0 * a2), \
            vr1 * a2 + vt1 * (h0 * a1 - h1 * a0)
        w0, w1, w2 = vr2 * b0 + vt2 * (h1 * b2 - h2 * b1), vr2 * b1 + vt2 * (h2 * b0 - h0 * b2), \
            vr2 * b2 + vt2 * (h0 * b1 - h1 * b0)
        if not (math.isfinite(u0) and math.isfinite(u1) and math.isfinite(u2)
                and math.isfinite(w0) and math.isfinite(w1) and math.isfinite(w2)):
            continue
        v1[k, 0], v1[k, 1], v1[k, 2] = u0, u1, u2
        v2[k, 0], v2[k, 1], v2[k, 2] = w0, w1, w2
        conv[k] = True
    return conv


def lambert(mu: float, r1, r2, tof, *, revolutions: int = 0, prograde: bool = True,
            low_path: bool = True) -> LambertSolution:
    """Solve Lambert's problem for one case or a batch.

    ``r1``, ``r2``: (3,) or (N, 3) positions in m; ``tof``: scalar or (N,) in s
    (broadcast against the positions); ``mu`` in m^3/s^2.  The leading shape of
    the input is kept: (3,) in gives (3,) velocities out.
    """
    r1b, r2b, tofb, single = broadcast_pair(r1, r2, tof)
    m = int(revolutions)
    if m < 0:
        raise ValueError("revolutions must be >= 0")
    n = tofb.shape[0]
    # contiguous float64 inputs: one compiled signature whatever the caller's layout
    r1c, r2c, tofc = (np.ascontiguousarray(a, dtype=np.float64) for a in (r1b, r2b, tofb))
    v1 = np.empty((n, 3))
    v2 = np.empty((n, 3))
    iters = np.empty(n, dtype=np.int64)
    conv = _solve(float(mu), r1c, r2c, tofc, m, bool(prograde), bool(low_path), v1, v2, iters)
    if single:
        return LambertSolution(v1=v1[0], v2=v2[0], converged=conv[0], iterations=iters[0])
    return LambertSolution(v1=v1, v2=v2, converged=conv, iterations=iters)



@njit(cache=True, error_model="numpy")
def _arc_min_radius(mu, r1, v1, r2, v2, revolutions, out):
    """The loop of :func:`arc_min_radius` (a compiled loop of its own: numpy's temporaries
    cost as much as the Lambert solve on a 1000 x 1000 porkchop)."""
    for k in range(r1.shape[0]):
        x1, y1, z1 = r1[k, 0], r1[k, 1], r1[k, 2]
        u0, u1, u2 = v1[k, 0], v1[k, 1], v1[k, 2]
        x2, y2, z2 = r2[k, 0], r2[k, 1], r2[k, 2]
        r1n = math.sqrt(x1 * x1 + y1 * y1 + z1 * z1)
        r2n = math.sqrt(x2 * x2 + y2 * y2 + z2 * z2)
        h0, h1, h2 = y1 * u2 - z1 * u1, z1 * u0 - x1 * u2, x1 * u1 - y1 * u0
        p = (h0 * h0 + h1 * h1 + h2 * h2) / mu                       # semi-latus rectum
        energy = 0.5 * (u0 * u0 + u1 * u1 + u2 * u2) - mu / r1n
        ecc = math.sqrt(max(0.0, 1.0 + 2.0 * energy * p / mu))
        rp = p / (1.0 + ecc)
        q = math.sqrt(p / mu)
        # e sin(nu) = sqrt(p/mu) (r . v) / r,  e cos(nu) = p / r - 1.  Is nu2 < nu1 with both in
        # [0, 2 pi)?  By half-planes and a cross product, not two atan2 (half the time here).
        s1, c1 = q * (x1 * u0 + y1 * u1 + z1 * u2) / r1n, p / r1n - 1.0
        s2, c2 = q * (x2 * v2[k, 0] + y2 * v2[k, 1] + z2 * v2[k, 2]) / r2n, p / r2n - 1.0
        half1 = 0 if (s1 > 0.0 or (s1 == 0.0 and c1 >= 0.0)) else 1      # 0: nu in [0, pi)
        half2 = 0 if (s2 > 0.0 or (s2 == 0.0 and c2 >= 0.0)) else 1
        wraps = half2 < half1 or (half2 == half1 and s1 * c2 - c1 * s2 > 0.0)
        val = rp if (revolutions > 0 or wraps) else min(r1n, r2n)
        out[k] = val if math.isfinite(rp) and math.isfinite(u0) and math.isfinite(u1) and math.isfinite(u2) \
            else math.nan


def arc_min_radius(mu: float, r1, v1, r2, v2, *, revolutions: int = 0) -> np.ndarray:
    """Smallest distance from the centre along the arc flown from (r1, v1) to (r2, v2): the
    transfer orbit's periapsis radius if the arc passes through periapsis, else min(|r1|, |r2|).

    Computed after the solve (the Lambert loop stays as fast), in a compiled loop of its own.
    With the true anomaly taken in [0, 2 pi) in the direction of motion, a zero-revolution
    arc passes periapsis exactly when the anomaly wraps around, ``nu2 < nu1``; the rule holds
    for hyperbolas too, whose anomalies lie in (-pi, pi).  An arc of one or more full
    revolutions passes periapsis.  NaN where the velocities are NaN (no solution).  Shapes
    as :func:`lambert`: (3,) vectors give a 0-d array.
    """
    v1a, v2a = np.asarray(v1, dtype=float), np.asarray(v2, dtype=float)
    single = v1a.ndim == 1 and np.ndim(r1) == 1 and np.ndim(r2) == 1
    n = max(np.atleast_2d(a).shape[0] for a in (r1, v1a, r2, v2a))
    r1c, v1c, r2c, v2c = (np.ascontiguousarray(np.broadcast_to(np.atleast_2d(np.asarray(a, dtype=float)), (n, 3)))
                          for a in (r1, v1a, r2, v2a))
    out = np.empty(n)
    _arc_min_radius(float(mu), r1c, v1c, r2c, v2c, int(revolutions), out)
    return out[0].copy() if single else out
