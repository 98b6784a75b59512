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
                      path_scale: np.ndarray) -> tuple[float, float, int] | None:
    """The worst gap ``H(u used) - min H`` over the admissible controls (module docstring), its time and the
    samples checked, at the samples ``dense = (t, x, u)`` of the re-flight; ``hf``: the phase's Hamiltonian."""
    ph = problem.phase
    td, xd, ud = (np.asarray(a, float) for a in dense)
    nx, nu = fns.nx, fns.nu
    S = td.size
    if not S:
        return None
    ld = np.vstack([np.interp(td, t_nodes, lam[i]) for i in range(nx)])
    lo, hi = np.empty(nu), np.empty(nu)
    for i, k in enumerate(ph.controls):
        span = max(float(np.ptp(ud[i])), 1.0)
        lo[i] = k.lower if k.lower is not None else float(np.min(ud[i])) - span
        hi[i] = k.upper if k.upper is not None else float(np.max(ud[i])) + span
    mixed = np.flatnonzero(hf.mixed)
    if mixed.size:
        used = np.asarray(fns.path.map(S)(td[None, :], xd, ud, att.theta, c, t0, att.tf))[mixed]
        lower = np.array([-np.inf if ph.path[j].lower is None else ph.path[j].lower for j in mixed])[:, None]
        upper = np.array([np.inf if ph.path[j].upper is None else ph.path[j].upper for j in mixed])[:, None]
        slack = FEASIBLE * np.asarray(path_scale, float)[mixed][:, None]
        # the used control's own excess is allowed too: the transcription holds a bound to its tolerance
        lower = lower - slack - np.maximum(lower - used, 0.0)
        upper = upper + slack + np.maximum(used - upper, 0.0)

    grid = nlp_grid
    if grid.piecewise:
        idx = np.clip(np.searchsorted(t_nodes, td, side="right") - 1, 0, grid.intervals - 1)
        count = np.maximum(np.bincount(idx, minlength=grid.intervals), 1)

        def pool(A: np.ndarray) -> np.ndarray:           # each sample gets its interval's average
            # summed by index, not through a samples x intervals matrix: that one was quadratic in the
            # intervals (410 MB at 800, 2.6 GB at 2,000)
            sums = np.zeros((A.shape[0], grid.intervals))
            np.add.at(sums.T, idx, A.T)          # sums.T is a view: the sums land in sums
            return (sums / count)[:, idx]
    else:
        def pool(A: np.ndarray) -> np.ndarray:
            return A

    def h_of(cand: np.ndarray) -> np.ndarray:            # cand (nu, n, S) -> H (n, S), inf where not admissible
        n = cand.shape[1]
        out = np.empty((n, S))
        bad = np.zeros((n, S), bool)
        # a block of candidates at a time: the tiled states and costates of every candidate at every sample
        # at once grew as candidates x samples x states (14 GB for 40 states and controls on 200 intervals)
        step = max(1, BLOCK // max(S * (2 * nx + nu + 2 * fns.npath + 1), 1))
        for a in range(0, n, step):
            k = min(step, n - a)
            flat = cand[:, a:a + k].reshape(nu, k * S)
            tt, xx = np.tile(td, k), np.tile(xd, k)
            out[a:a + k] = evaluate(hf.H, t=tt, X=xx, U=flat, att=att, c=c, t0=t0,
                                    lam=np.tile(ld, k)).reshape(k, S)
            if mixed.size:
                P = np.asarray(fns.path.map(k * S)(tt[None, :], xx, flat, att.theta, c, t0, att.tf))[mixed]
                P = P.reshape(mixed.size, k, S)
                bad[a:a + k] = np.any((P < lower[:, None, :]) | (P > upper[:, None, :]), axis=0)
        out = pool(out)
        if mixed.size:
            if grid.piecewise:
                bad = pool(bad.astype(float)) > 0.0       # a constant control: the whole interval
            out = np.where(bad, np.inf, out)
        return out

    sets = []
    if nu <= CORNERS:
        grids = np.meshgrid(*[[lo[i], hi[i]] for i in range(nu)], indexing="ij")
        corners = np.vstack([g.ravel() for g in grids])                     # (nu, 2^nu)
        sets.append(np.repeat(corners[:, :, None], S, axis=2))
    for i in range(nu):
        line = np.repeat(ud[:, None, :], GRID, axis=1)
        line[i] = np.linspace(lo[i], hi[i], GRID)[:, None]
        sets.append(line)
    cand = np.concatenate(sets, axis=1)
    Hc = h_of(cand)
    best = cand[:, np.argmin(Hc, axis=0), np.arange(S)]                    # (nu, S)
    Hmin = np.min(Hc, axis=0)
    for i in range(nu):         # refine within one grid step of the best, control by control
        step = (hi[i] - lo[i]) / (GRID - 1)
        line = np.repeat(best[:, None, :], ZOOM, axis=1)
        line[i] = np.clip(best[i][None, :] + np.linspace(-step, step, ZOOM)[:, None], lo[i], hi[i])
        Hz = h_of(line)
        better = np.min(Hz, axis=0) < Hmin
        best[:, better] = line[:, np.argmin(Hz, axis=0), np.arange(S)][:, better]
        Hmin = np.minimum(Hmin, np.min(Hz, axis=0))
    used_H = pool(evaluate(hf.H, t=td, X=xd, U=ud, att=att, c=c, t0=t0, lam=ld)[0][None, :])[0]
    gap = np.where(np.isfinite(Hmin), np.maximum(used_H - Hmin, 0.0), 0.0)
    worst = int(np.argmax(gap))
    return float(gap[worst]), float(td[worst]), S
