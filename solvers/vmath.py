"""Branch-free exp, log, pow, sin and cos for numba loops that LLVM is to vectorize.

The llvmlite numba ships is not SVML-patched, so ``math.exp``/``math.sin``/``math.cos`` in a loop
are calls into libm, and a loop with a call in it is not vectorized.  These versions are plain
arithmetic, comparisons that become selects, and two bit casts (:func:`f2i`, :func:`i2f`), all of
which LLVM turns into AVX2 instructions four lanes at a time.  Every operation is IEEE and no
``fastmath`` is used, so a lane's result does not depend on which lane (or the scalar remainder
loop) computed it.

Methods (error against the exact value, from an extended-precision reference, measured in
``tests/unit/test_vmath.py``; within 1.5 ulp each: under 1 ulp of approximation, 1/2 of rounding):

* :func:`exp`: Cody-Waite reduction ``x = n ln2 + r``, ``|r| <= ln2/2`` (fdlibm's two-part
  ``ln2HI``/``ln2LO``), the Taylor polynomial of degree 13 (truncation 4e-18 relative) by Estrin's
  scheme, scaling by ``2^n`` built in the exponent bits (two factors, so that the whole range
  over- and underflows as libm does).  1.0 ulp measured.
* :func:`sincos`: reduction by pi/2 held in three doubles (each step one fma, the product exact
  inside it), fdlibm's minimax kernels ``__kernel_sin``/``__kernel_cos`` on ``|r| <= pi/4``, the
  quadrant by selects.  1.4 ulp measured for ``|x| <= 8`` (the angles of a flight, also next to the
  zeros of sin and cos), under 2 ulp up to 1e4; meant for ``|x| < 2^19`` (no Payne-Hanek reduction).
* :func:`log`: fdlibm's ``__ieee754_log`` (``x = 2^k (1 + f)``, ``s = f / (2 + f)``, minimax
  ``Lg1..Lg7``) with the exponent split by bit arithmetic and the terms summed exactly into a
  head and a tail.  0.8 ulp measured for positive normal x.
* :func:`pow_pos`: ``x^y = e^(y hi) (1 + y lo + err(y hi))`` from that head and tail, so the
  rounding of the exponent does not reach the result: 1.5 ulp for the heating fit's
  ``(1e-4 v / ft)^3.07`` over 300 m/s .. 12 km/s.

Numba's on-disk cache keys a compiled function on its own source file only: after editing this
module, delete the cached kernels that inline it (``solvers/__pycache__/robust_reentry_kernel.*.nb?``).
"""
from __future__ import annotations

from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def f2i(typingctx, x):
    """The bits of a float64 as an int64 (no conversion)."""
    if x != types.float64:
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def i2f(typingctx, n):
    """The float64 whose bits are the int64 ``n``."""
    if n != types.int64:
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


@intrinsic
def fma(typingctx, a, b, c):
    """``a b + c`` rounded once (``llvm.fma``: one vfmadd on FMA hardware, the same bits anywhere)."""
    if not (a == b == c == types.float64):
        return None

    def codegen(context, builder, sig, args):
        f64 = ir.DoubleType()
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(f64, [f64, f64, f64]), "llvm.fma.f64")
        return builder.call(fn, args)

    return types.float64(types.float64, types.float64, types.float64), codegen


# x + MAGIC rounds x to an integer held in the low mantissa bits (|x| < 2^51): no float->int64
# conversion, which AVX2 does not have for vectors.
_MAGIC = 6755399441055744.0          # 1.5 * 2^52
_MAGIC_BITS = 0x4338000000000000
_ONE_EXP = 1023 << 52

_LOG2E = 1.4426950408889634074
_LN2_HI = 6.93147180369123816490e-01   # fdlibm ln2HI: n * _LN2_HI exact for |n| < 2^20
_LN2_LO = 1.90821492927058770002e-10
# 1/k!, k = 2..13
_E2, _E3, _E4, _E5 = 1.0 / 2.0, 1.0 / 6.0, 1.0 / 24.0, 1.0 / 120.0
_E6, _E7, _E8, _E9 = 1.0 / 720.0, 1.0 / 5040.0, 1.0 / 40320.0, 1.0 / 362880.0
_E10, _E11, _E12, _E13 = 1.0 / 3628800.0, 1.0 / 39916800.0, 1.0 / 479001600.0, 1.0 / 6227020800.0


@njit(inline="always", error_model="numpy")
def _pow2(nf):
    """2^nf for an integer-valued float ``nf`` in -1022 .. 1023 (exact)."""
    return i2f(((f2i(nf + _MAGIC) - _MAGIC_BITS) << 52) + _ONE_EXP)


@njit(inline="always", error_model="numpy")
def exp(x):
    """e^x within 1 ulp; inf above 709.78, 0 below -745.13, NaN for NaN."""
    # clamp so that n fits the two scale factors; NaN passes through (comparisons are false)
    xc = -746.0 if x < -746.0 else x  # not min/max: what NaN does is the point
    xc = 710.0 if xc > 710.0 else xc
    nf = fma(xc, _LOG2E, _MAGIC) - _MAGIC
    r = fma(-nf, _LN2_LO, fma(-nf, _LN2_HI, xc))      # the inner one is exact
    # e^r = 1 + r + r^2 q(r), q of degree 11 by Estrin's scheme: a dependency chain of 4 fma
    # instead of Horner's 12 (the loops that call this are latency-bound)
    r2 = r * r
    r4 = r2 * r2
    q01 = fma(fma(_E5, r, _E4), r2, fma(_E3, r, _E2))
    q23 = fma(fma(_E9, r, _E8), r2, fma(_E7, r, _E6))
    q45 = fma(fma(_E13, r, _E12), r2, fma(_E11, r, _E10))
    p = 1.0 + fma(r2, fma(q45, r4 * r4, fma(q23, r4, q01)), r)
    # 2^n in two factors (|n| <= 1077 does not fit one); for NaN p is NaN and carries it
    h = (nf * 0.5 + _MAGIC) - _MAGIC
    return (p * _pow2(h)) * _pow2(nf - h)


# pi/2 in three doubles (the sum within 6e-50 of pi/2)
_PIO2_1, _PIO2_2, _PIO2_3 = 1.5707963267948966, 6.123233995736766e-17, -1.4973849048591698e-33
_2_PI = 6.36619772367581382433e-01
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@njit(inline="always", error_model="numpy")
def sincos(x):
    """``(sin x, cos x)`` within 1 ulp for ``|x| < 2^19``; NaN for NaN and infinities."""
    t = fma(x, _2_PI, _MAGIC)
    nf = t - _MAGIC
    q = f2i(t) & 3                      # the quadrant, n mod 4 (two's complement low bits)
    # Cody-Waite with fma: each product is exact inside the fma, and x - n pio2_1 is exact where
    # it cancels (near the zeros of sin and cos), so r keeps its relative accuracy there as well
    r = fma(-nf, _PIO2_3, fma(-nf, _PIO2_2, fma(-nf, _PIO2_1, x)))
    z = r * r
    v = z * r
    ps = fma(z, fma(z, fma(z, fma(z, _S6, _S5), _S4), _S3), _S2)
    s = fma(v, fma(z, ps, _S1), r)
    pc = z * fma(z, fma(z, fma(z, fma(z, fma(z, _C6, _C5), _C4), _C3), _C2), _C1)
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + fma(z, pc, ((1.0 - w) - hz))
    odd = (q & 1) != 0
    a = c if odd else s
    b = s if odd else c
    sn = -a if (q & 2) != 0 else a
    cs = -b if ((q + 1) & 2) != 0 else b
    return sn, cs


_SQRT1_2_BITS = 0x3FE6A09E667F3BCD   # bits of sqrt(2)/2
_MANT = (1 << 52) - 1
_LG1, _LG2, _LG3 = 6.666666666666735130e-01, 3.999999999940941908e-01, 2.857142874366239149e-01
_LG4, _LG5, _LG6 = 2.222219843214978396e-01, 1.818357216161805012e-01, 1.531383769920937332e-01
_LG7 = 1.479819860511658591e-01


@njit(inline="always", error_model="numpy")
def _log2(x):
    """ln x as ``hi + lo`` (``hi`` the rounded value, ``lo`` a few bits beyond) for positive normal
    x: fdlibm's ``__ieee754_log`` with its terms ``k ln2_hi + f + (the rest)`` summed by Fast2Sum
    (``|k ln2_hi| >= |f|`` unless k = 0, and the rest is below f^2/2)."""
    ix = f2i(x) - _SQRT1_2_BITS
    kf = i2f((ix >> 52) + _MAGIC_BITS) - _MAGIC          # exponent with 1+f in [sqrt(2)/2, sqrt(2))
    f = i2f((ix & _MANT) + _SQRT1_2_BITS) - 1.0
    s = f / (2.0 + f)
    z = s * s
    w = z * z
    t1 = w * fma(w, fma(w, _LG6, _LG4), _LG2)
    t2 = z * fma(w, fma(w, fma(w, _LG7, _LG5), _LG3), _LG1)
    rr = t2 + t1
    hfsq = 0.5 * f * f
    a = kf * _LN2_HI                                      # exact
    h1 = a + f
    c = ((a - h1) + f) + ((s * (hfsq + rr) + kf * _LN2_LO) - hfsq)
    hi = h1 + c                                           # Fast2Sum again: |h1| >= |c|
    return hi, (h1 - hi) + c


@njit(inline="always", error_model="numpy")
def log(x):
    """ln x within 1 ulp (-inf at 0, NaN below, inf at inf; subnormal x not handled)."""
    hi, lo = _log2(x)
    special = -_INF if x == 0.0 else (_NAN if x < 0.0 else x)     # 0, negative, inf, NaN
    return hi + lo if (x > 0.0) & (x < _INF) else special


_INF = float("inf")
_NAN = float("nan")


@njit(inline="always", error_model="numpy")
def pow_pos(x, y):
    """x^y for x >= 0 and y > 0: ``e^(y hi) (1 + y lo + the rounding error of y hi)`` with
    ``ln x = hi + lo`` from :func:`_log2`, so the exponent's rounding does not reach the result."""
    hi, lo = _log2(x)
    p = y * hi
    e = exp(p)
    out = fma(e, fma(y, hi, -p) + y * lo, e)
    special = 0.0 if x == 0.0 else (_NAN if x < 0.0 else x)       # 0, negative, inf, NaN
    return out if (x > 0.0) & (x < _INF) else special
