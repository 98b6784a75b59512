"""Path limits of several ``ocp`` phases held between the nodes: :mod:`solvers.ocp.limits` across phases.

Each phase's dense re-flight gives, per path constraint and interval, the worst scaled excess; where
it is positive, that interval's nodes get the bound moved inwards by the excess plus a quarter of
the tolerance (cumulatively; a node takes the larger margin of its two intervals), in that phase's
rows of the one multi-phase NLP, which is solved again warm from the previous answer and its
multipliers; until every limit of every phase holds, or :data:`solvers.ocp.limits.MAX_ROUNDS`
rounds, keeping the best answer (the first that holds, else the smallest worst excess).
"""
from __future__ import annotations

import numpy as np

from solvers.ocp.limits import MAX_ROUNDS
from solvers.ocp.verify import LIMIT_TOLERANCE


def _worst(ev) -> float:
    return max((float(e.max()) for per in ev.excess for e in (per or [])), default=-np.inf)


def hold_phase_limits(*, solver, rows, bounds, p, res, ev, evaluate, should_stop=None):
    """``rows``: per phase ``(global slice of its path rows or None, number of path constraints, grid)``;
    ``bounds``: ``(lbz, ubz, lbg, ubg)`` of the NLP; ``evaluate(res) -> ev`` re-flies every phase.
    Returns ``(res, ev, rounds)`` of the best answer."""
    lbz, ubz, lbg, ubg = bounds
    margins = [np.zeros((n, grid.intervals)) for _, n, grid in rows]
    best = (_worst(ev), res, ev)
    rounds: list[dict] = []
    for k in range(1, MAX_ROUNDS + 1):
        if ev.limits_held or (should_stop is not None and should_stop()):
            break
        lo, hi = lbg.copy(), ubg.copy()
        for i, (sl, n, grid) in enumerate(rows):
            if sl is None or not n:
                continue
            for j, e in enumerate(ev.excess[i]):
                margins[i][j] += np.where(e > LIMIT_TOLERANCE, e + 0.25 * LIMIT_TOLERANCE, 0.0)
            left, right = grid.node_intervals_both()
            node = np.maximum(margins[i][:, left], margins[i][:, right]).ravel(order="F")
            hi[sl] = np.where(np.isfinite(hi[sl]), hi[sl] - node, hi[sl])
            lo[sl] = np.where(np.isfinite(lo[sl]), np.minimum(lo[sl] + node, hi[sl]), lo[sl])
        r = solver.solve(x0=res.x, lbx=lbz, ubx=ubz, lbg=lo, ubg=hi, p=p, lam_x0=res.lam_x, lam_g0=res.lam_g,
                         should_stop=should_stop, expected_iterations=15, label=f"limit round {k}")
        rounds.append({"round": k, "status": r.status.solver_status, "iterations": r.status.iterations,
                       "solve_time_s": r.status.solve_time_s,
                       "max_margin_scaled": float(max((m.max() for m in margins if m.size), default=0.0))})
        if not r.status.ok:
            break
        res, ev = r, evaluate(r)
        rounds[-1]["worst_excess_scaled"] = _worst(ev)
        if ev.limits_held or _worst(ev) < best[0]:
            best = (_worst(ev), res, ev)
        if ev.limits_held:
            break
    _, res, ev = best
    return res, ev, rounds
