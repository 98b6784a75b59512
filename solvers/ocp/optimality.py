"""Evidence that a phase's answer is an optimum, not only feasible (``shared/specs/ocp.md``, "Optimality").

Costates from the NLP's multipliers, for multiple shooting: the defect of interval ``k`` is
``g_k = (F_k(x_k, u) - x_{k+1}) / x_scale`` and IPOPT's Lagrangian ``f + mu' g``, so the sensitivity
of the minimised objective to the state at node ``k+1`` is ``lambda_{k+1} = mu_k / x_scale`` (the
discrete adjoint of the RK4 map, Betts, *Practical Methods*, 2nd ed., sec. 4.11); at the first node
the adjoint is carried back through interval 0, ``lambda_0 = dF_0/dx' lambda_1 + sign dq_0/dx``.
The costates are those of the objective as minimised (``-J`` for a maximum).  The Hamiltonian at the
nodes is ``H = sign L + lambda' f`` (path constraints' multipliers are not included yet).

Checks (each ``{"value", "tolerance", "held"}``), those that apply: ``hamiltonian_constant`` (the
dynamics and integrand do not name ``t``: the variation of H over the nodes), ``hamiltonian_final``
(a free final time of a problem posed as one phase: ``H(tf) = -sign dPhi/dtf``), ``stationarity``
(``dH/du = 0`` at the nodes where every control is strictly inside its bounds and every path
constraint inside its own, and so are both neighbours), ``minimum_principle`` (module function
:func:`minimum_principle`: the control used minimises H over its box at the dense re-flight's samples).
Each is measured
against the size of H's terms (the largest sum of their magnitudes over the nodes, as H itself may
be 0) and held to the agreement tolerance of the answer
(``accuracy`` or 1%): the transcription's own error bounds how well its multipliers estimate the
costates.  Not yet: LGL costates (Benson/Garg/Rao mapping), transversality; a phase transcribed by LGL carries no ``optimality``.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

INSIDE = 1e-3        # a control within this fraction of its bounds' span from a bound is on it
GRID = 41            # candidate values along each control's range (minimum principle)
ZOOM = 21            # candidates of the refinement around the best one, within one grid step
CORNERS = 6          # at most this many controls have all their bounds' corners tried


def costates(*, nlp, num, att, mu: np.ndarray, t_nodes: np.ndarray, c: np.ndarray, t0: float) -> np.ndarray | None:
    """``(nx, N)`` costates at the nodes of a multiple-shooting phase (module docstring), else None."""
    from solvers.ocp.phase import ms_interval

    g, fns = nlp.grid, nlp.fns
    if g.method != "multiple_shooting":
        return None
    nx, m = fns.nx, g.intervals
    lam = np.zeros((nx, g.n_nodes))
    lam[:, 1:] = (np.asarray(mu, float).reshape((m, nx)).T) / num.x_scale[:, None]
    F = ms_interval(fns, g)
    xa, ua, ub = ca.SX.sym("xa", nx), ca.SX.sym("ua", fns.nu), ca.SX.sym("ub", fns.nu)
    ta, h = ca.SX.sym("ta"), ca.SX.sym("h")
    th, cc, s0, sf = ca.SX.sym("th", fns.ntheta), ca.SX.sym("c", fns.nc), ca.SX.sym("t0"), ca.SX.sym("tf")
    xe, q = F(xa, ua, ub, ta, h, th, cc, s0, sf)
    lam1 = ca.SX.sym("l1", nx)
    back = ca.gradient(ca.dot(lam1, xe) + (nlp.sign * q[0] if fns.nq else 0), xa)
    fn = ca.Function("ocp_adjoint_0", [xa, ua, ub, ta, h, th, cc, s0, sf, lam1], [back])
    U = att.U
    u1 = U[:, 1] if U.shape[1] > 1 and g.control == "linear" else U[:, 0]
    lam[:, 0] = np.asarray(fn(att.X[:, 0], U[:, 0], u1, t_nodes[0], t_nodes[1] - t_nodes[0], att.theta, c, t0,
                              att.tf, lam[:, 1])).ravel()
    return lam


def hamiltonian(*, nlp, att, lam: np.ndarray, U: np.ndarray, t_nodes: np.ndarray, c,
                t0: float) -> tuple[np.ndarray, float]:
    """H at the nodes (module docstring), and the size of its terms (the largest sum of their magnitudes
    over the nodes: what a check's error is measured against, as H itself may be near 0)."""
    fns = nlp.fns
    F = np.asarray(fns.rhs.map(t_nodes.size)(t_nodes[None, :], att.X, U, att.theta, c, t0, att.tf))
    terms = lam * F[:fns.nx]
    H, size = np.sum(terms, axis=0), np.sum(np.abs(terms), axis=0)
    if fns.nq:
        H, size = H + nlp.sign * F[fns.nx], size + np.abs(F[fns.nx])
    return H, float(np.max(size, initial=0.0))


def path_inside(*, fns, phase, t: np.ndarray, X: np.ndarray, U: np.ndarray, att, c, t0: float) -> np.ndarray:
    """Where every path constraint is strictly inside its bounds (by INSIDE of their size) at the samples ``t``:
    an active path constraint's multiplier is not in H, so the checks judge H only there."""
    keep = np.ones(t.size, bool)
    if not fns.npath:
        return keep
    P = np.asarray(fns.path.map(t.size)(t[None, :], X, U, att.theta, c, t0, att.tf))
    for j, k in enumerate(phase.path):
        span = max(abs(k.lower or 0.0), abs(k.upper or 0.0), 1e-300)
        if k.lower is not None:
            keep &= P[j] > k.lower + INSIDE * span
        if k.upper is not None:
            keep &= P[j] < k.upper - INSIDE * span
    return keep


def minimum_principle(*, problem, fns, nlp_grid, sign: float, att, lam: np.ndarray, t_nodes: np.ndarray, c, t0: float,
                      dense: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[float, float, int] | None:
    """The worst gap ``H(u used) - min H`` over the box of the controls, its time and the samples checked.

    At the samples ``dense = (t, x, u)`` of the re-flight (the nodes and the points between them), with
    the costates interpolated linearly between the nodes.  A sample where a path constraint is on its
    bound is left out (its multiplier restricts the admissible set).  The candidates: the bounds' corners,
    a grid along each control's range with the others as used, then a finer grid around the best of
    those within one step, control by control.  The minimum over candidates is an upper bound of the true
    one, so the gap is a lower bound: a grid never flags an answer that does minimise H.  A control
    without a bound is searched over the range it uses widened by that range (at least 1) each way.
    Piecewise-constant controls hold one value over an interval, so there H is averaged over each
    interval's samples before it is compared (the transcription's own minimum principle): pointwise, the
    nodal costates' error near a switch on a node (the multipliers are not unique there) would move the
    switching function's zero off the node and flag the exact bang-bang answer.
    """
    ph = problem.phase
    td, xd, ud = (np.asarray(a, float) for a in dense)
    nx, nu = fns.nx, fns.nu
    keep = path_inside(fns=fns, phase=ph, t=td, X=xd, U=ud, att=att, c=c, t0=t0)
    if not keep.any():
        return None
    td, xd, ud = td[keep], xd[:, keep], ud[:, keep]
    S = td.size
    ld = np.vstack([np.interp(td, t_nodes, lam[i]) for i in range(nx)])
    lo, hi = np.empty(nu), np.empty(nu)
    for i, k in enumerate(ph.controls):
        span = max(float(np.ptp(ud[i])), 1.0)
        lo[i] = k.lower if k.lower is not None else float(np.min(ud[i])) - span
        hi[i] = k.upper if k.upper is not None else float(np.max(ud[i])) + span
    t, x, u = ca.SX.sym("t"), ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    th, cc, s0, sf = ca.SX.sym("th", fns.ntheta), ca.SX.sym("c", fns.nc), ca.SX.sym("t0"), ca.SX.sym("tf")
    ls = ca.SX.sym("lam", nx)
    f = fns.rhs(t, x, u, th, cc, s0, sf)
    Hf = ca.Function("ocp_H", [t, x, u, th, cc, s0, sf, ls],
                     [ca.dot(ls, f[:nx]) + (sign * f[nx] if fns.nq else 0)])

    grid = nlp_grid
    if grid.method == "multiple_shooting" and grid.control == "constant":
        idx = np.clip(np.searchsorted(t_nodes, td, side="right") - 1, 0, grid.intervals - 1)
        member = np.zeros((S, grid.intervals))
        member[np.arange(S), idx] = 1.0
        member /= np.maximum(member.sum(axis=0), 1.0)

        def pool(A: np.ndarray) -> np.ndarray:           # each sample gets its interval's average
            return (A @ member)[:, idx]
    else:
        def pool(A: np.ndarray) -> np.ndarray:
            return A

    def h_of(cand: np.ndarray) -> np.ndarray:            # cand (nu, n, S) -> H (n, S)
        n = cand.shape[1]
        out = Hf.map(n * S)(np.tile(td, n)[None, :], np.tile(xd, n), cand.reshape(nu, n * S), att.theta, c,
                            t0, att.tf, np.tile(ld, n))
        return pool(np.asarray(out).reshape(n, S))

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
    gap = np.maximum(h_of(ud[:, None, :])[0] - Hmin, 0.0)
    worst = int(np.argmax(gap))
    return float(gap[worst]), float(td[worst]), S


def checks(*, problem, nlp, att, lam, U, t_nodes, c, t0: float, H: np.ndarray, size: float, single: bool,
           tolerance: float, dense: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> dict:
    """``verification.optimality`` of the phase (module docstring); ``size``: the size of H's terms;
    ``dense``: the re-flight's ``(t, x, u)`` samples, for the minimum principle (none: not checked)."""
    fns, ph = nlp.fns, problem.phase
    scale = size if size > 0.0 else 1.0
    out: dict[str, dict] = {}
    t, x, u = ca.SX.sym("t"), ca.SX.sym("x", fns.nx), ca.SX.sym("u", fns.nu)
    th, cc, s0, sf = ca.SX.sym("th", fns.ntheta), ca.SX.sym("c", fns.nc), ca.SX.sym("t0"), ca.SX.sym("tf")
    f = fns.rhs(t, x, u, th, cc, s0, sf)
    if not ca.depends_on(f, t) and not ca.depends_on(f, s0) and not ca.depends_on(f, sf):
        value = float(np.max(H) - np.min(H)) / scale
        out["hamiltonian_constant"] = {"value": value, "tolerance": tolerance, "held": bool(value <= tolerance)}
    if single and ph.time.final is None:
        x0, xf = ca.SX.sym("x0", fns.nx), ca.SX.sym("xf", fns.nx)
        u0, uf = ca.SX.sym("u0", fns.nu), ca.SX.sym("uf", fns.nu)
        mayer = fns.events(s0, sf, x0, xf, u0, uf, th, cc)[1]
        dphi = ca.Function("ocp_dphi_dtf", [s0, sf, x0, xf, u0, uf, th, cc], [ca.jacobian(mayer, sf)])
        want = -nlp.sign * float(dphi(t0, att.tf, att.X[:, 0], att.X[:, -1], U[:, 0], U[:, -1], att.theta, c))
        value = abs(float(H[-1]) - want) / scale
        out["hamiltonian_final"] = {"value": value, "expected": want, "tolerance": tolerance,
                                    "held": bool(value <= tolerance)}
    if fns.nu:
        lam_s = ca.SX.sym("lam", fns.nx)
        Hs = ca.dot(lam_s, f[:fns.nx]) + (nlp.sign * f[fns.nx] if fns.nq else 0)
        dH = ca.Function("ocp_dH_du", [t, x, u, th, cc, s0, sf, lam_s], [ca.gradient(Hs, u)])
        G = np.asarray(dH.map(t_nodes.size)(t_nodes[None, :], att.X, U, att.theta, c, t0, att.tf, lam))
        inside = np.ones(t_nodes.size, bool)
        for i, k in enumerate(ph.controls):
            span = (k.upper - k.lower) if k.lower is not None and k.upper is not None else max(1.0, np.ptp(U[i]))
            if k.lower is not None:
                inside &= U[i] > k.lower + INSIDE * span
            if k.upper is not None:
                inside &= U[i] < k.upper - INSIDE * span
        # an active path constraint's multiplier is not in H: its nodes are left out
        inside &= path_inside(fns=fns, phase=ph, t=t_nodes, X=att.X, U=U, att=att, c=c, t0=t0)
        # a node next to one on a bound shares an interval with it (its controls interpolate into the arc)
        own = inside.copy()
        inside[1:] &= own[:-1]
        inside[:-1] &= own[1:]
        uscale = np.array([max(abs(k.lower or 0.0), abs(k.upper or 0.0), 1e-300) if k.scale is None else k.scale
                           for k in ph.controls])
        if inside.any():
            value = float(np.max(np.abs(G[:, inside]) * uscale[:, None])) / scale
            out["stationarity"] = {"value": value, "tolerance": tolerance, "held": bool(value <= tolerance),
                                   "nodes": int(inside.sum())}
        mp = None if dense is None else minimum_principle(problem=problem, fns=fns, nlp_grid=nlp.grid,
                                                          sign=nlp.sign, att=att, lam=lam, t_nodes=t_nodes,
                                                          c=c, t0=t0, dense=dense)
        if mp is not None:
            value = mp[0] / scale
            out["minimum_principle"] = {"value": value, "tolerance": tolerance, "held": bool(value <= tolerance),
                                        "t": mp[1], "samples": mp[2]}
    held = all(v["held"] for v in out.values())
    failed = [k for k, v in out.items() if not v["held"]]
    message = (f"checked {', '.join(out) or 'nothing that applies'}; "
               + ("held" if held else f"NOT held: {', '.join(failed)}"))
    return {"held": held, "checks": out, "message": message}
