"""Path limits that hold between the nodes: tighten where the dense re-propagation exceeds them, re-solve.

The reentry kind's loop (``solvers/reentry_limits.py``) generalised to any path constraint with a
lower and/or upper bound, in every phase: per phase and interval, the worst scaled excess of each
constraint on the dense grid (:mod:`solvers.ocp.verify`); where it is positive, that interval's
nodes get the bound moved inwards by the excess plus a quarter of the tolerance (cumulatively; a
node takes the larger margin of its two intervals), as *bounds* of the existing constraint rows of
that phase, so no rebuild.  The solve loop (:meth:`solvers.ocp.solver.OcpSolve.hold_limits`)
re-solves warm from the previous answer and its multipliers, and stops when every limit holds to
the tolerance, or after :data:`MAX_ROUNDS` rounds, keeping the best answer (the first that holds,
else the one with the smallest worst excess), reporting ``limit_not_held`` when it still fails.
"""
from __future__ import annotations

import numpy as np

from solvers.ocp.verify import LIMIT_TOLERANCE

MAX_ROUNDS = 5


def worst_excess(checks) -> float:
    """The worst scaled excess of any path constraint of any phase (-inf without one)."""
    return max((float(e.max()) for c in checks for e in c.verification.interval_excess), default=-np.inf)


class Margins:
    """The cumulative inward margins of every phase's path rows (module docstring)."""

    def __init__(self, rows):
        """``rows``: per phase ``(slice of its path rows in g or None, number of path constraints, grid)``."""
        self.rows = rows
        self.margins = [np.zeros((n, grid.intervals)) for _, n, grid in rows]

    def tighten(self, checks, lbg: np.ndarray, ubg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add this answer's excesses (``checks``: one per phase) and return the tightened bounds."""
        lo, hi = lbg.copy(), ubg.copy()
        for i, ((sl, n, grid), check) in enumerate(zip(self.rows, checks)):
            if sl is None or not n:
                continue
            for j, e in enumerate(check.verification.interval_excess):
                self.margins[i][j] += np.where(e > LIMIT_TOLERANCE, e + 0.25 * LIMIT_TOLERANCE, 0.0)
            left, right = grid.node_intervals_both()
            node = np.maximum(self.margins[i][:, left], self.margins[i][:, right]).ravel(order="F")
            hi[sl] = np.where(np.isfinite(hi[sl]), hi[sl] - node, hi[sl])
            lo[sl] = np.where(np.isfinite(lo[sl]), np.minimum(lo[sl] + node, hi[sl]), lo[sl])
        return lo, hi

    def words(self) -> dict:
        """What a round's record says of the margins."""
        return {"max_margin_scaled": float(max((m.max() for m in self.margins if m.size), default=0.0)),
                "tightened_intervals": int(sum(np.count_nonzero(m.max(axis=0)) for m in self.margins if m.size))}
