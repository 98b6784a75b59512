"""Path limits that hold between the nodes: tighten where the dense re-propagation exceeds them, re-solve.

The reentry kind's loop (``solvers/reentry_limits.py``) generalised to any path constraint with a
lower and/or upper bound: per interval, the worst scaled excess of each constraint on the dense
grid (:mod:`solvers.ocp.verify`); where it is positive, that interval's nodes get the bound moved
inwards by the excess plus a quarter of the tolerance (cumulatively; a node takes the larger
margin of its two intervals), as *bounds* of the existing constraints, so no rebuild; re-solve
warm from the previous answer and its multipliers; stop when every limit holds to the tolerance,
or after :data:`MAX_ROUNDS` rounds, keeping the best answer (the first that holds, else the one
with the smallest worst excess).  The caller reports ``limit_not_held`` when it still fails.
"""
from __future__ import annotations

import numpy as np

from solvers.ocp.verify import LIMIT_TOLERANCE

MAX_ROUNDS = 5


def hold_path_limits(*, problem, nlp, num, attempt, verification, verify, make_attempt, should_stop=None):
    """Returns ``(attempt, verification, rounds)`` (module docstring)."""
    ph, grid = problem.phase, nlp.grid
    npath, m = len(ph.path), grid.intervals
    left, right = grid.node_intervals_both()
    margins = np.zeros((npath, m))
    rounds: list[dict] = []

    def worst(ver):
        return max((float(e.max()) for e in ver.interval_excess), default=-np.inf)

    best = (worst(verification), attempt, verification)
    att, ver = attempt, verification
    for k in range(1, MAX_ROUNDS + 1):
        if ver.limits_held or (should_stop is not None and should_stop()):
            break
        for i, e in enumerate(ver.interval_excess):
            margins[i] += np.where(e > LIMIT_TOLERANCE, e + 0.25 * LIMIT_TOLERANCE, 0.0)
        node_margin = np.maximum(margins[:, left], margins[:, right]).ravel(order="F")   # (npath*N,)
        lbg, ubg = num.lbg.copy(), num.ubg.copy()
        sl = num.path_slices
        ubg[sl] = np.where(np.isfinite(ubg[sl]), ubg[sl] - node_margin, ubg[sl])
        lbg[sl] = np.where(np.isfinite(lbg[sl]), np.minimum(lbg[sl] + node_margin, ubg[sl]), lbg[sl])
        prev = att.res
        res = nlp.solver.solve(x0=prev.x, lbx=num.lbz, ubx=num.ubz, lbg=lbg, ubg=ubg, p=num.p,
                               lam_x0=prev.lam_x, lam_g0=prev.lam_g, should_stop=should_stop,
                               expected_iterations=15, label=f"limit round {k}")
        rounds.append({"round": k, "status": res.status.solver_status, "iterations": res.status.iterations,
                       "solve_time_s": res.status.solve_time_s,
                       "max_margin_scaled": float(margins.max()),
                       "tightened_intervals": int(np.count_nonzero(margins.max(axis=0)))})
        if not res.status.ok:
            break
        att = make_attempt(res)
        ver = verify(att)
        rounds[-1]["worst_excess_scaled"] = worst(ver)
        if ver.limits_held or worst(ver) < best[0]:
            best = (worst(ver), att, ver)
        if ver.limits_held:
            break
    _, att, ver = best
    return att, ver, rounds
