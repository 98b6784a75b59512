"""Lambert branches of the impulsive interception (paper 003, method II) and the delta-v of
one branch over a batch of burn states, with transfers through the planet left out.

Shared by the maneuver-time scan (:mod:`solvers.intercept`) and the porkchop map
(:mod:`solvers.intercept.porkchop`).  A Lambert arc from the burn point to the target may
dive below the Earth's surface on its way (a fast arc through periapsis); such an arc is no
transfer, so by default its delta-v is NaN and it is counted (issue 15: a third of random
answers passed through the planet unflagged).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.astro.lambert import arc_min_radius, lambert


@dataclass(frozen=True)
class Branch:
    """One Lambert solution family."""

    prograde: bool
    revolutions: int
    low_path: bool = True

    def label(self) -> str:
        way = "prograde" if self.prograde else "retrograde"
        if self.revolutions == 0:
            return f"{way}, 0 revolutions"
        return f"{way}, {self.revolutions} revolutions, {'low' if self.low_path else 'high'} path"


def branches(*, max_revolutions: int, retrograde: bool) -> list[Branch]:
    """Prograde (and retrograde) branches with 0..max_revolutions revolutions, both paths above 0."""
    out = []
    for prograde in ((True, False) if retrograde else (True,)):
        out.append(Branch(prograde, 0))
        for m in range(1, max_revolutions + 1):
            out.append(Branch(prograde, m, True))
            out.append(Branch(prograde, m, False))
    return out


@dataclass
class BranchDeltaV:
    """Delta-v of one branch over a batch: vectors (N, 3), NaN where no admissible transfer."""

    delta_v_mps: np.ndarray
    v_arrival_mps: np.ndarray
    through_planet: np.ndarray    # (N,) bool: converged, but the arc dips below body_radius_m


def delta_v(mu: float, r, v, r_target, tof, branch: Branch, *, body_radius_m: float | None) -> BranchDeltaV:
    """Delta-v from burn states ``(r, v)`` onto ``branch``'s arc to ``r_target`` in ``tof``.

    ``body_radius_m``: arcs whose smallest radius is below it get NaN (None: no check).
    """
    sol = lambert(mu, r, r_target, tof, revolutions=branch.revolutions, prograde=branch.prograde,
                  low_path=branch.low_path)
    dv = sol.v1 - v
    through = np.zeros(np.shape(sol.converged), bool)
    if body_radius_m is not None:
        through = np.asarray(arc_min_radius(mu, r, sol.v1, r_target, sol.v2, revolutions=branch.revolutions)
                             < body_radius_m)
        if through.any():
            dv = np.where(through[..., None], np.nan, dv)
    return BranchDeltaV(dv, sol.v2, through)
