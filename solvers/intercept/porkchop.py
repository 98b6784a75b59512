"""The porkchop map of the impulsive interception: single-impulse delta-v over maneuver
time x interception time, the minimum over the Lambert branches (paper 003 spec, "what users
expect beyond the paper").

Every cell is one Lambert problem per branch, solved in one batched call per branch; arcs
through the planet are left out like in the scan (:mod:`solvers.intercept.branches`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.astro.kepler import propagate
from solvers.astro.lambert import arc_min_radius, lambert
from solvers.intercept.branches import Branch

_BLOCK = 32768

@dataclass(frozen=True)
class PorkchopSettings:
    """A 2-D map of delta-v over maneuver time x interception time."""

    t_man_points: int = 60
    t_intercept_points: int = 60
    t_man_min_s: float = 0.0
    t_man_max_s: float | None = None          # None: the largest interception time
    t_intercept_min_s: float | None = None    # None: t1 / 2
    t_intercept_max_s: float | None = None    # None: 1.5 t1


@dataclass
class Porkchop:
    t_man_s: np.ndarray          # (P,)
    t_intercept_s: np.ndarray    # (Q,)
    delta_v_mps: np.ndarray      # (P, Q), NaN where t_man >= t_intercept or no solution
    best_t_man_s: float
    best_t_intercept_s: float
    best_delta_v_mps: float


def porkchop_map(pc: PorkchopSettings, *, mu: float, t1: float, interceptor, target, branches: list[Branch],
                 body_radius_m: float | None) -> Porkchop:
    """Delta-v over (maneuver time, interception time), min over ``branches``.

    ``interceptor``, ``target``: ``(r, v)`` at t0; ``t1``: the nominal interception time the
    default windows are relative to; ``body_radius_m``: leave out arcs below it (None: keep all).
    """
    ti_lo = 0.5 * t1 if pc.t_intercept_min_s is None else pc.t_intercept_min_s
    ti_hi = 1.5 * t1 if pc.t_intercept_max_s is None else pc.t_intercept_max_s
    tm_hi = ti_hi if pc.t_man_max_s is None else pc.t_man_max_s
    t_man = np.linspace(pc.t_man_min_s, tm_hi, pc.t_man_points, endpoint=pc.t_man_max_s is not None)
    t_int = np.linspace(ti_lo, ti_hi, pc.t_intercept_points)
    r_m, v_m = propagate(mu, interceptor[0], interceptor[1], t_man)
    r_i, _ = propagate(mu, target[0], target[1], t_int)
    tof_all = (t_int[None, :] - t_man[:, None]).ravel()
    ok = tof_all > 0.0
    cells = np.flatnonzero(ok)
    sub = np.full(cells.size, np.inf)
    # blocks of cells small enough for the temporaries to stay in cache (one 1e6-cell block ran
    # at half the solve rate of 10k-cell blocks)
    for lo in range(0, cells.size, _BLOCK):
        blk = cells[lo:lo + _BLOCK]
        row, col = blk // t_int.size, blk % t_int.size
        rm, vm, ri, tof = r_m[row], v_m[row], r_i[col], tof_all[blk]
        best_blk = sub[lo:lo + _BLOCK]
        for branch in branches:
            sol = lambert(mu, rm, ri, tof, revolutions=branch.revolutions, prograde=branch.prograde,
                          low_path=branch.low_path)
            dv = sol.v1 - vm
            d = np.sqrt(np.einsum("ij,ij->i", dv, dv))
            better = d < best_blk                    # NaN compares False: unsolved cells stay out
            if body_radius_m is not None:
                better &= arc_min_radius(mu, rm, sol.v1, ri, sol.v2,
                                         revolutions=branch.revolutions) >= body_radius_m
            np.copyto(best_blk, d, where=better)
    best = np.full(ok.size, np.nan)
    best[ok] = np.where(np.isfinite(sub), sub, np.nan)
    grid = best.reshape(t_man.size, t_int.size)
    if np.isfinite(grid).any():
        i, j = np.unravel_index(np.nanargmin(grid), grid.shape)
        return Porkchop(t_man, t_int, grid, float(t_man[i]), float(t_int[j]), float(grid[i, j]))
    return Porkchop(t_man, t_int, grid, float("nan"), float("nan"), float("nan"))
