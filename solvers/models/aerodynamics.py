"""Aerodynamic tables: CL and CD against angle of attack (degrees) and Mach number.

A vehicle's aerodynamics are either Betts-style polynomials in alpha degrees
(:class:`solvers.models.shuttle.Vehicle` ``cl_coeffs``/``cd_coeffs``) or an :class:`AeroTable`,
as real vehicles' databases come.  The table is interpolated by a cubic B-spline
(:mod:`solvers.models.tables`), smooth with exact derivatives.  Its values are baked into the
built NLP (the table is part of the solver cache key, as the atmosphere is): with the values as
an input of the spline (NLP parameters) IPOPT's derivative evaluations took 33 s instead of
1.2 s on the Betts case, 100 intervals.  The ``cd_scale``/``cl_scale`` multipliers stay
parameters.  Inputs are clamped to the table's range (no cubic extrapolation).  Mach is ``v / a(h)``
with the atmosphere's speed of sound (:meth:`solvers.models.atmosphere.Atmosphere.speed_of_sound`).
A table with one Mach breakpoint is a table in alpha alone.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from solvers.models import tables


@dataclass(frozen=True)
class AeroTable:
    """``cl[i][j]``, ``cd[i][j]`` at ``alpha_deg[i]``, ``mach[j]`` (rows alpha, columns Mach)."""

    alpha_deg: tuple
    mach: tuple
    cl: Sequence | np.ndarray   # rows alpha, columns Mach: nested tuples or a 2-D array
    cd: Sequence | np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "alpha_deg", tables.check_breakpoints(self.alpha_deg, "alpha_deg", minimum=4))
        object.__setattr__(self, "mach", tables.check_breakpoints(self.mach, "mach", minimum=1))
        if len(self.mach) in (2, 3):
            raise ValueError("mach needs 1 breakpoint (no Mach dependence) or at least 4")
        for name in ("cl", "cd"):
            a = np.asarray(getattr(self, name), float)
            if a.shape != self.shape:
                raise ValueError(f"{name} must have shape {self.shape} (alpha x mach), got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{name} must be finite")
            object.__setattr__(self, name, tuple(tuple(float(v) for v in row) for row in a))

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.alpha_deg), len(self.mach)

    @property
    def grid(self) -> tuple[tuple[float, ...], ...]:
        """The spline's axes: alpha, and Mach unless the table has a single Mach breakpoint."""
        return (self.alpha_deg,) if len(self.mach) == 1 else (self.alpha_deg, self.mach)

    @property
    def size(self) -> int:
        return self.shape[0] * self.shape[1]

    def values(self, name: str) -> tuple[float, ...]:
        """``cl`` or ``cd`` flattened alpha-fastest (the spline's layout)."""
        return tuple(np.asarray(getattr(self, name), float).ravel(order="F"))

    def coefficient(self, name: str, alpha_deg, mach, xp):
        """``CL`` or ``CD`` at ``alpha_deg`` and ``mach`` (numbers, arrays or CasADi symbols)."""
        a = tables.clamp(alpha_deg, self.alpha_deg[0], self.alpha_deg[-1], xp)
        points = [a]
        if len(self.mach) > 1:
            points.append(tables.clamp(mach, self.mach[0], self.mach[-1], xp))
        return tables.evaluate(tables.spline(self.grid, self.values(name)), points, xp=xp)


def sample_polynomials(*, cl_coeffs, cd_coeffs, alpha_deg, mach=(1.0,)) -> AeroTable:
    """A table sampled from alpha-degree polynomials (lowest order first), the same at every Mach."""
    a = np.asarray(alpha_deg, float)
    cl = np.polynomial.polynomial.polyval(a, cl_coeffs)
    cd = np.polynomial.polynomial.polyval(a, cd_coeffs)
    ones = np.ones(len(mach))
    return AeroTable(alpha_deg=tuple(a), mach=tuple(mach), cl=np.outer(cl, ones), cd=np.outer(cd, ones))
