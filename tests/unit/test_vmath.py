"""solvers.vmath (the branch-free exp, sincos, log, pow of the vectorized Monte Carlo kernel) against
the exact values, in ulp, over the ranges the reentry kernel feeds them and beyond; special values.

The reference is the x87 extended-precision libm (``np.longdouble``: 64-bit significand, glibc's
``expl``/``logl``/``sinl``/``powl`` within an ulp of *that* format, 2^-11 of a double's ulp), the
same on every x86-64 CPU.  numpy's float64 functions are no reference: with AVX-512 numpy
dispatches ``power`` and others to SIMD kernels of a few ulp, so a bound measured against them is
the bound of one CPU.  vmath's own bits do not depend on the CPU (every contraction is an explicit
``llvm.fma``, no fast-math), so each bound below is the method's: the approximation's error
(under 1 ulp, from the kernels' published error) plus the final rounding (1/2 ulp).
"""
from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from solvers import vmath as vm


@njit(error_model="numpy")
def _exp(x, out):
    for i in range(x.size):
        out[i] = vm.exp(x[i])


@njit(error_model="numpy")
def _sincos(x, s, c):
    for i in range(x.size):
        s[i], c[i] = vm.sincos(x[i])


@njit(error_model="numpy")
def _log(x, out):
    for i in range(x.size):
        out[i] = vm.log(x[i])


@njit(error_model="numpy")
def _pow(x, y, out):
    for i in range(x.size):
        out[i] = vm.pow_pos(x[i], y)


def _apply(fn, x, *extra):
    out = np.empty_like(x)
    fn(x, *extra, out)
    return out


LD = np.longdouble
# approximation error below 1 ulp (exp: degree-13 Taylor, truncation 4e-18 relative; sincos and
# log: fdlibm's kernels; pow: exp of a double-double y log x) plus 1/2 ulp for the final rounding
BOUND_ULP = 1.5


def _ulp(got, exact):
    """Largest error of ``got`` in units of the last place of the correctly rounded value, ``exact``
    being an extended-precision reference (see the module docstring)."""
    ref = exact.astype(np.float64)
    assert np.array_equal(np.isfinite(got), np.isfinite(ref))
    ok = np.isfinite(ref) & (ref != 0)
    return float(np.max(np.abs(got[ok].astype(LD) - exact[ok]) / np.spacing(np.abs(ref[ok])).astype(LD)))


RNG = np.random.default_rng(16)


@pytest.mark.parametrize("lo, hi", [(-20.0, 1.0), (-745.0, 709.7)])
def test_exp_within_its_bound(lo, hi):
    # -20..1: -h / H of the exponential atmosphere; then the whole finite range
    x = np.concatenate([RNG.uniform(lo, hi, 400_000), np.linspace(lo, hi, 100_001)])
    assert _ulp(_apply(_exp, x), np.exp(x.astype(LD))) <= BOUND_ULP


def test_exp_special_values():
    x = np.array([0.0, -0.0, 1e-300, 709.78, 709.79, 710.0, 1e300, np.inf, -745.1, -745.2, -1e300, -np.inf,
                  -708.5, -720.0, np.nan])
    with np.errstate(over="ignore"):
        ref = np.exp(x.astype(LD)).astype(np.float64)  # rounded once from extended precision: the same on every CPU
    got = _apply(_exp, x)
    assert np.array_equal(got, ref, equal_nan=True)


@pytest.mark.parametrize("hi", [4.0, 8.0, 1e4])
def test_sincos_within_ulps(hi):
    # flight path angle, heading and latitude stay within a few radians; 2 ulp allowed further out
    x = np.concatenate([RNG.uniform(-hi, hi, 400_000), np.linspace(-hi, hi, 100_001)])
    s, c = np.empty_like(x), np.empty_like(x)
    _sincos(x, s, c)
    # further out the three-double reduction by pi/2 loses up to half an ulp more
    bound = BOUND_ULP if hi <= 8.0 else 2.0
    assert _ulp(s, np.sin(x.astype(LD))) <= bound
    assert _ulp(c, np.cos(x.astype(LD))) <= bound


def test_sincos_next_to_the_zeros_and_special_values():
    # the reduction keeps its relative accuracy where sin or cos is small (heading near 90 deg)
    k = np.arange(-40, 41)[:, None] * (np.pi / 2)
    x = (k + np.array([0.0, 3e-16, -1e-12, 1e-9, -1e-6, 1e-3])[None, :]).ravel()
    s, c = np.empty_like(x), np.empty_like(x)
    _sincos(x, s, c)
    assert _ulp(s, np.sin(x.astype(LD))) <= BOUND_ULP
    assert _ulp(c, np.cos(x.astype(LD))) <= BOUND_ULP
    x = np.array([np.inf, -np.inf, np.nan])
    s, c = np.empty_like(x), np.empty_like(x)
    _sincos(x, s, c)
    assert np.isnan(s).all() and np.isnan(c).all()


def test_log_within_its_bound_and_special_values():
    x = np.concatenate([RNG.uniform(0.01, 10.0, 400_000), np.exp(RNG.uniform(-700, 700, 400_000)),
                        np.array([1.0, 2.0, 0.5, 2.2250738585072014e-308, 1.7976931348623157e308])])
    assert _ulp(_apply(_log, x), np.log(x.astype(LD))) <= BOUND_ULP
    x = np.array([0.0, -1.0, np.inf, np.nan])
    with np.errstate(divide="ignore", invalid="ignore"):
        assert np.array_equal(_apply(_log, x), np.log(x), equal_nan=True)


def test_pow_of_the_heating_fit():
    # (1e-4 v / ft)^3.07 for speeds from 300 m/s to 12 km/s: y log x within [-7, 5.3]
    x = np.concatenate([RNG.uniform(0.098, 3.94, 400_000), np.linspace(0.098, 3.94, 100_001)])
    assert _ulp(_apply(_pow, x, 3.07), np.power(x.astype(LD), LD(3.07))) <= BOUND_ULP
    assert np.array_equal(_apply(_pow, np.array([0.0, np.inf, np.nan]), 3.07), np.array([0.0, np.inf, np.nan]),
                          equal_nan=True)
