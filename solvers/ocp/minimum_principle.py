"""The minimum principle of one ``ocp`` phase checked between the nodes: the control used minimises the
Hamiltonian (:mod:`solvers.ocp.hamiltonian`) over its admissible set at the samples of the dense re-flight.

The admissible set is the controls' box intersected with the mixed path constraints (those naming a
control): a candidate control that breaks one at the sample is not admissible there (Hartl, Sethi &
Vickson, "A survey of the maximum principles for optimal control problems with state constraints", SIAM
Review 37(2), 1995, informal theorem 4.1: with the constraints adjoined directly, H is minimised over the
controls the mixed constraints allow; a pure state constraint names no control and leaves the set alone).
The costates are interpolated linearly between the nodes.

The candidates: the box's corners, a grid along each control's range with the others as used, then a
finer grid around the best of those within one step, control by control.  The minimum over candidates is
an upper bound of the true one, so the gap is a lower bound: a grid never flags an answer that does
minimise H.  A control without a bound is searched over the range it uses widened by that range (at least
1) each way.  Piecewise-constant controls hold one value over an interval, so there H is averaged over
each interval's samples before it is compared (the transcription's own minimum principle): pointwise, the
nodal costates' error near a switch on a node (the multipliers are not unique there) would move the
switching function's zero off the node and flag the exact bang-bang answer.

The samples are checked a block of whole intervals at a time, and H at a block's candidates a ``block`` of
numbers at a time: every sample's answer depends on its own interval alone, so the blocks change nothing
but the memory, which stays bounded whatever the problem's width and length (candidates x samples at once
took 2.6 GB on 20 controls over 150 intervals).
"""
from __future__ import annotations

import numpy as np

from solvers.ocp.hamiltonian import HamiltonianFunctions, evaluate

GRID = 41            # candidate values along each control's range
ZOOM = 21            # candidates of the refinement around the best one, within one grid step
BLOCK = 2_000_000      # numbers evaluated at once (16 MB of doubles per array)
CORNERS = 6          # at most this many controls have all their bounds' corners tried
FEASIBLE = 1e-6      # a candidate may exceed a mixed constraint's bound by this fraction of its scale


def minimum_principle(*, problem, fns, hf: HamiltonianFunctions, nlp_grid, att, lam: np.ndarray,
                      t_nodes: np.ndarray, c, t0: float, dense: tuple[np.ndarray, np.ndarray, np.ndarray],
                      path_scale: np.ndarray, block: int = BLOCK) -> tuple[float, float, int] | None:
    """The worst gap ``H(u used) - min H`` over the admissible controls (module docstring), its time and the
    samples checked, at the samples ``dense = (t, x, u)`` of the re-flight; ``hf``: the phase's Hamiltonian.
    ``block``: numbers evaluated (and candidate numbers held) at once; the answer does not depend on it."""
    ph = problem.phase
    td, xd, ud = (np.asarray(a, float) for a in dense)
    nu = fns.nu
    S = td.size
    if not S:
        return None
    lo, hi = np.empty(nu), np.empty(nu)
    for i, k in enumerate(ph.controls):
        span = max(float(np.ptp(ud[i])), 1.0)
        lo[i] = k.lower if k.lower is not None else float(np.min(ud[i])) - span
        hi[i] = k.upper if k.upper is not None else float(np.max(ud[i])) + span
    if nlp_grid.piecewise:      # each sample's interval: H is averaged over it
        group = np.clip(np.searchsorted(t_nodes, td, side="right") - 1, 0, nlp_grid.intervals - 1)
    else:                       # each sample on its own
        group = np.arange(S)
    order = np.argsort(group, kind="stable")       # an interval's samples side by side, in their order
    ld = np.vstack([np.interp(td, t_nodes, lam[i]) for i in range(fns.nx)])
    check = _Block(problem=problem, fns=fns, hf=hf, att=att, c=c, t0=t0, lo=lo, hi=hi,
                   path_scale=np.asarray(path_scale, float), piecewise=nlp_grid.piecewise, block=block)
    gap = np.empty(S)
    for cut in sample_blocks(group[order], most=check.samples_at_once()):
        cols = order[cut]
        gap[cols] = check.gaps(td[cols], xd[:, cols], ud[:, cols], ld[:, cols], group[cols])
    worst = int(np.argmax(gap))
    return float(gap[worst]), float(td[worst]), S


def sample_blocks(group: np.ndarray, *, most: int) -> list[slice]:
    """Consecutive slices of ``group`` (sorted labels), each of whole groups and at most ``most`` long unless
    one group alone is longer."""
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    ends = np.r_[starts[1:], group.size]
    out, a = [], 0
    while a < starts.size:
        b = max(a + 1, int(np.searchsorted(ends, starts[a] + most, side="right")))
        out.append(slice(int(starts[a]), int(ends[b - 1])))
        a = b
    return out


def candidate_count(nu: int) -> int:
    """Candidates per sample before the refinement: the box's corners (up to CORNERS controls) and the grids."""
    return GRID * nu + (2 ** nu if nu <= CORNERS else 0)


class _Block:
    """The check at one block of samples (whole intervals): its candidates, H there, their minima."""

    def __init__(self, *, problem, fns, hf, att, c, t0, lo, hi, path_scale, piecewise: bool, block: int):
        self.ph, self.fns, self.hf, self.att, self.c, self.t0 = problem.phase, fns, hf, att, c, t0
        self.lo, self.hi, self.path_scale, self.piecewise, self.block = lo, hi, path_scale, piecewise, block
        self.mixed = np.flatnonzero(hf.mixed)
        self.rows = 2 * fns.nx + fns.nu + 2 * fns.npath + 1     # numbers per column of an evaluation of H
        nu = fns.nu
        self.corners = None
        if nu <= CORNERS:
            grids = np.meshgrid(*[[lo[i], hi[i]] for i in range(nu)], indexing="ij")
            self.corners = np.vstack([g.ravel() for g in grids])                 # (nu, 2^nu)
        self.lines = np.vstack([np.linspace(lo[i], hi[i], GRID) for i in range(nu)])   # (nu, GRID)

    def samples_at_once(self) -> int:
        """Samples per block: its candidates and its refinement's evaluations within ``block`` numbers."""
        per_sample = max(self.fns.nu * candidate_count(self.fns.nu), self.rows * ZOOM)
        return max(1, self.block // per_sample)

    def gaps(self, td, xd, ud, ld, group) -> np.ndarray:
        """``H(u used) - min H`` at each sample of the block (0 where no candidate is admissible)."""
        fns, ph, nu, Sb = self.fns, self.ph, self.fns.nu, td.size
        first = np.r_[True, group[1:] != group[:-1]]
        starts, seg = np.flatnonzero(first), np.cumsum(first) - 1
        count = np.bincount(seg)
        args = {"att": self.att, "c": self.c, "t0": self.t0}
        mixed = self.mixed
        if mixed.size:
            used = np.asarray(fns.path.map(Sb)(td[None, :], xd, ud, self.att.theta, self.c, self.t0,
                                               self.att.tf))[mixed]
            lower = np.array([-np.inf if ph.path[j].lower is None else ph.path[j].lower for j in mixed])[:, None]
            upper = np.array([np.inf if ph.path[j].upper is None else ph.path[j].upper for j in mixed])[:, None]
            slack = FEASIBLE * self.path_scale[mixed][:, None]
            # the used control's own excess is allowed too: the transcription holds a bound to its tolerance
            lower = lower - slack - np.maximum(lower - used, 0.0)
            upper = upper + slack + np.maximum(used - upper, 0.0)

        def pool(A: np.ndarray) -> np.ndarray:           # each sample gets its interval's average
            if not self.piecewise:
                return A
            # summed by index in the samples' order, as the unblocked check did: the same sums to the bit
            sums = np.zeros((A.shape[0], count.size))
            np.add.at(sums.T, seg, A.T)          # sums.T is a view: the sums land in sums
            return (sums / count)[:, seg]

        def h_of(cand: np.ndarray) -> np.ndarray:        # cand (nu, n, Sb) -> H (n, Sb), inf where not admissible
            n = cand.shape[1]
            out = np.empty((n, Sb))
            bad = np.zeros((n, Sb), bool)
            # a few candidates at a time: the tiled states and costates grow as candidates x samples x states
            step = max(1, self.block // max(Sb * self.rows, 1))
            for a in range(0, n, step):
                k = min(step, n - a)
                flat = cand[:, a:a + k].reshape(nu, k * Sb)
                tt, xx = np.tile(td, k), np.tile(xd, k)
                out[a:a + k] = evaluate(self.hf.H, t=tt, X=xx, U=flat, lam=np.tile(ld, k), **args).reshape(k, Sb)
                if mixed.size:
                    P = np.asarray(fns.path.map(k * Sb)(tt[None, :], xx, flat, self.att.theta, self.c, self.t0,
                                                        self.att.tf))[mixed].reshape(mixed.size, k, Sb)
                    bad[a:a + k] = np.any((P < lower[:, None, :]) | (P > upper[:, None, :]), axis=0)
            out = pool(out)
            if mixed.size:
                if self.piecewise:                       # a constant control: the whole interval
                    bad = np.logical_or.reduceat(bad, starts, axis=1)[:, seg]
                out = np.where(bad, np.inf, out)
            return out

        cand = np.repeat(ud[:, None, :], candidate_count(nu), axis=1)
        at = 0
        if self.corners is not None:
            at = self.corners.shape[1]
            cand[:, :at] = self.corners[:, :, None]
        for i in range(nu):
            cand[i, at + i * GRID:at + (i + 1) * GRID] = self.lines[i][:, None]
        Hc = h_of(cand)
        best = cand[:, np.argmin(Hc, axis=0), np.arange(Sb)]                   # (nu, Sb)
        del cand
        Hmin = np.min(Hc, axis=0)
        for i in range(nu):         # refine within one grid step of the best, control by control
            step = (self.hi[i] - self.lo[i]) / (GRID - 1)
            line = np.repeat(best[:, None, :], ZOOM, axis=1)
            line[i] = np.clip(best[i][None, :] + np.linspace(-step, step, ZOOM)[:, None], self.lo[i], self.hi[i])
            Hz = h_of(line)
            better = np.min(Hz, axis=0) < Hmin
            best[:, better] = line[:, np.argmin(Hz, axis=0), np.arange(Sb)][:, better]
            Hmin = np.minimum(Hmin, np.min(Hz, axis=0))
        used_H = pool(evaluate(self.hf.H, t=td, X=xd, U=ud, lam=ld, **args)[0][None, :])[0]
        return np.where(np.isfinite(Hmin), np.maximum(used_H - Hmin, 0.0), 0.0)
