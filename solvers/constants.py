"""Physical constants used by more than one model, defined once (SI).

Planet-specific constants live with their planet (``solvers.astro.j2`` for
Earth's mu, J2 and radius; the Betts shuttle constants in
``solvers.models.shuttle``); only the ones that are not tied to a model sit here.
"""
from __future__ import annotations

G0_MPS2 = 9.80665  # standard gravity (CGPM 1901): rocket equation, load factor
