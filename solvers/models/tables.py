"""Smooth, differentiable table lookup shared by the aerodynamic and atmosphere tables.

One mechanism for both: CasADi's cubic B-spline ``interpolant`` (exact first and second
derivatives for IPOPT).  The same CasADi function serves the numpy paths (verification, Monte
Carlo, guesses) by being called on arrays, so the optimizer and the checks evaluate the same
spline and cannot disagree.  CasADi is imported lazily: the API process loads these modules to
validate tables without it.

:func:`spline` bakes the values into the function: a table is part of the problem's
structure (and of the solver cache key), as the exponential and US 1976 atmospheres are.
CasADi's parametric B-spline (values as an input) made IPOPT's derivative evaluations about 25x
slower on the Betts case, so it is not used.

Inputs outside the breakpoints are clamped to the table's range before the lookup (a cubic
extrapolation can turn over); the atmosphere extends its log-density linearly instead
(:mod:`solvers.models.atmosphere`).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np


def check_breakpoints(values, name: str, *, minimum: int = 2) -> tuple[float, ...]:
    """The breakpoints as a tuple of floats; strictly increasing, finite, at least ``minimum``."""
    a = np.asarray(values, float).ravel()
    if a.size < minimum:
        raise ValueError(f"{name} needs at least {minimum} breakpoints, got {a.size}")
    if not np.all(np.isfinite(a)) or not np.all(np.diff(a) > 0):
        raise ValueError(f"{name} must be finite and strictly increasing")
    return tuple(float(v) for v in a)


@lru_cache(maxsize=64)
def spline(grid: tuple[tuple[float, ...], ...], values: tuple[float, ...]):
    """``f(x)``: cubic B-spline on ``grid`` with fixed ``values`` (column-major)."""
    import casadi as ca
    return ca.interpolant("table_" + "x".join(str(len(g)) for g in grid), "bspline",
                          [list(g) for g in grid], list(values))


def evaluate(fn, points: list, *, xp):
    """``fn(vertcat(points))`` on CasADi symbols, or on numpy arrays of any broadcastable shapes
    (returns an array of the broadcast shape)."""
    if xp is np:
        arrays = np.broadcast_arrays(*[np.asarray(p, float) for p in points])
        shape = arrays[0].shape
        out = np.asarray(fn(np.vstack([a.reshape(1, -1) for a in arrays]))).reshape(shape)
        return out if shape else float(out)
    return fn(xp.vertcat(*points))


def clamp(value, lo: float, hi: float, xp):
    """``value`` clamped to ``[lo, hi]`` (numpy or CasADi)."""
    if xp is np:
        return np.clip(value, lo, hi)
    return xp.fmin(xp.fmax(value, lo), hi)
