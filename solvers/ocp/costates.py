"""Costates of an ``ocp`` phase from the NLP's multipliers, for both transcriptions, and what the ends'
multipliers say the costates and the Hamiltonian must be there.

IPOPT's Lagrangian is ``f + nu' g``; every defect row is scaled by its state's scale (``g = d / x_scale``),
so ``nu / x_scale`` is the multiplier of the physical defect.  The costates are those of the objective as
minimised (``-J`` for a maximum).

*Multiple shooting* (defect ``F_k(x_k, u) - x_{k+1}``): the multiplier of interval ``k``'s defect is the
sensitivity of the minimised objective to the state at node ``k+1``, ``lambda_{k+1} = nu_k / x_scale``
(the discrete adjoint of the RK4 map, Betts, *Practical Methods*, 2nd ed., sec. 4.11); at the first node
the adjoint is carried back through interval 0, ``lambda_0 = dF_0/dx' lambda_1 + sign dq_0/dx``.

*LGL* (the integral form of :mod:`solvers.transcription.lgl`: ``X_i - X_0 - (h/2) sum_j A_ij F_j`` for
``i = 1..n-1`` on each segment): the KKT condition of an interior node ``j`` reads ``(h/2) w_j dH/dx(lambda_j)
= -nu_j`` with ``lambda_j = -(sum_i A_ij nu_i) / w_j``: the integral form's costate mapping, multipliers
over the quadrature weights as in Fahroo & Ross's covector mapping for the differential LGL form
("Costate estimation by a Legendre pseudospectral method", JGCD 24(2), 2001) and Benson's for the Gauss
form (Benson, Huntington, Thorvaldsen & Rao, JGCD 29(6), 2006, with its endpoint corrections); here it
follows from the KKT conditions above, and tests/unit/test_ocp_costates.py holds it to closed forms at
fourth order.  A node shared by
two segments takes the mean of their two estimates.  The ends get the endpoint corrections, from the exact
KKT conditions of the first and last nodes: ``lambda(t0) = -sum_i nu_i + (h/2) w_0 dH/dx`` and
``lambda(tf) = -nu_{n-1} - (h/2) w_{n-1} dH/dx``: these equal what the boundary multipliers say
(``-d(Phi + nu' psi)/dx0`` and ``d(Phi + nu' psi)/dxf`` with the bounds' multipliers), and the mapping's own
end values are held to them by the ``transversality`` check (:mod:`solvers.ocp.optimality`).

:func:`multipliers_of` splits an answer's multipliers by phase: the defects', the path constraints' at
the nodes, the bounds' on the phase's columns, and the gradient of the events (the Mayer term, the
boundary constraints, the links between phases and the path constraints at the nodes, each weighted by
its multiplier) with respect to the phase's columns: what the ends' conditions read.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from solvers.ocp.phase import ms_interval
from solvers.transcription.lgl import lgl_integration_matrix, lgl_weights


@dataclass
class PhaseMultipliers:
    """One phase's share of an answer's multipliers (module docstring); scaled as the NLP has them."""

    defects: np.ndarray           # the defect rows, in the order of the phase's elements
    path: np.ndarray              # (npath, nodes) the path rows
    bounds: np.ndarray            # lam_x of the phase's columns ([tf, theta, X, U])
    lower: np.ndarray             # the columns' bounds as placed (scaled): an end is free where they differ
    upper: np.ndarray
    ends: np.ndarray              # d(events' Lagrangian: Mayer, boundary rows, links)/d(the phase's columns)
    path_ends: np.ndarray         # d(path rows' nu' g)/d(the phase's columns): a node's point multipliers


def _event_like(name: str) -> bool:
    tail = name.rsplit(":", 1)[-1]
    return tail in ("boundary", "events", "path")


def multipliers_of(nlp, res, p: np.ndarray, lbz: np.ndarray, ubz: np.ndarray) -> list[PhaseMultipliers]:
    """Each phase's multipliers (module docstring) of the answer ``res`` of the problem's NLP ``nlp``
    (:class:`solvers.ocp.trajectory.TrajectoryNLP`) with parameters ``p`` and column bounds ``lbz, ubz``."""
    elements = nlp.elements()
    grad, pgrad = np.zeros(nlp.nz), np.zeros(nlp.nz)
    lam_g, z = np.asarray(res.lam_g, float), np.asarray(res.x, float)
    per_phase: dict[int, dict[str, list]] = {i: {"defects": [], "path": []} for i in range(len(nlp.blocks))}
    names = [b.name for b in nlp.blocks]
    offset = 0
    for el in elements:
        rows = el.ny * el.count
        mu = lam_g[offset:offset + rows].reshape((el.count, el.ny)).T if rows else np.zeros((0, el.count))
        offset += rows
        head, _, tail = el.name.rpartition(":")
        which = 0 if not head else (names.index(head) if head in names else None)
        if which is not None and tail in ("defects", "path"):
            per_phase[which][tail].append(mu)
        if not _event_like(el.name):
            continue
        nw = el.cols.shape[1]
        w, ps, k = ca.SX.sym("w", nw), ca.SX.sym("p", el.fn.size1_in(1)), ca.SX.sym("k", el.fn.size1_in(2))
        m = ca.SX.sym("mu", el.ny)
        y, f = el.fn(w, ps, k)
        g = ca.Function("ocp_end_gradient", [w, ps, k, m], [ca.gradient(f + ca.dot(m, y), w)])
        W = z[el.cols].T
        K = np.asarray(el.kvals, float).reshape(el.count, -1).T
        G = np.asarray(g.map(el.count)(W, p, K, mu))
        np.add.at(pgrad if tail == "path" else grad, el.cols.ravel(), G.T.ravel())
    out = []
    lam_x = np.asarray(res.lam_x, float)
    for i, b in enumerate(nlp.blocks):
        d = per_phase[i]
        path = d["path"][0] if d["path"] else np.zeros((0, b.nlp.grid.n_nodes))
        out.append(PhaseMultipliers(defects=np.concatenate([m.T.ravel() for m in d["defects"]]), path=path,
                              lower=np.asarray(lbz, float)[b.colmap], upper=np.asarray(ubz, float)[b.colmap],
                              bounds=lam_x[b.colmap], ends=grad[b.colmap], path_ends=pgrad[b.colmap]))
    return out


def costates(*, nlp, num, att, mu: np.ndarray, t_nodes: np.ndarray, c, t0: float,
             hx=None) -> tuple[np.ndarray, dict]:
    """``(nx, N)`` costates at the nodes of a phase (module docstring) from its defects' multipliers ``mu``,
    and the LGL mapping's own values at the ends (``{"initial", "final"}``, for transversality; none for
    multiple shooting).  ``hx(j, lam)``: ``dH/dx`` at node ``j`` with costate ``lam`` (LGL's end corrections)."""
    if nlp.grid.method == "multiple_shooting":
        return _shooting(nlp=nlp, num=num, att=att, mu=mu, t_nodes=t_nodes, c=c, t0=t0), {}
    return _lgl(nlp=nlp, num=num, mu=mu, t_nodes=t_nodes, hx=hx)


def right_costates(*, nlp, num, mult: PhaseMultipliers, lam: np.ndarray) -> np.ndarray:
    """The costates at the start of each node's right interval.  In multiple shooting a node's state bound
    and path rows act at the node: its KKT condition ``lambda_j = dF_j/dx' lambda_{j+1} + sign dq_j/dx +
    zeta_j + pi_j dc/dx`` makes the costate jump there by the bound's and the path rows' multipliers (a state
    constraint's arc spreads them over its nodes), so an interval starts from ``lambda_j`` less that jump.
    The first node's estimate is already its right value; LGL's mapped costates need no such split."""
    if nlp.grid.method != "multiple_shooting":
        return lam
    fns, N = nlp.fns, nlp.grid.n_nodes
    cols = (1 + fns.ntheta + np.arange(fns.nx * N)).reshape((N, fns.nx)).T
    jump = (mult.bounds[cols] + mult.path_ends[cols]) / num.x_scale[:, None]
    jump[:, 0] = 0.0
    return lam - jump


def _shooting(*, nlp, num, att, mu, t_nodes, c, t0: float) -> np.ndarray:
    g, fns = nlp.grid, nlp.fns
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


def _lgl(*, nlp, num, mu, t_nodes, hx) -> tuple[np.ndarray, dict]:
    g, nx = nlp.grid, nlp.fns.nx
    per, off = g.nodes_per_interval(), g.offsets()
    N = g.n_nodes
    acc, count = np.zeros((nx, N)), np.zeros(N)
    nu_of: dict[int, np.ndarray] = {}
    mu = np.asarray(mu, float)
    row = 0
    for n in sorted(set(per.tolist())):
        for s in np.flatnonzero(per == n):
            block = mu[row:row + nx * (n - 1)].reshape((n - 1, nx)).T / num.x_scale[:, None]    # (nx, n-1)
            row += nx * (n - 1)
            nu_of[int(s)] = block
            A, w = np.asarray(lgl_integration_matrix(n)), np.asarray(lgl_weights(n))
            lam_s = -(block @ A[1:, :]) / w[None, :]
            nodes = off[s] + np.arange(n)
            acc[:, nodes] += lam_s
            count[nodes] += 1
    lam = acc / count[None, :]
    mapped = {"initial": lam[:, 0].copy(), "final": lam[:, -1].copy()}
    if hx is not None:
        first, last = nu_of[0], nu_of[g.intervals - 1]
        n0, nN = int(per[0]), int(per[-1])
        h0, hN = t_nodes[off[1]] - t_nodes[0], t_nodes[-1] - t_nodes[off[-2]]
        lam[:, 0] = -first.sum(axis=1) + 0.5 * h0 * lgl_weights(n0)[0] * hx(0, mapped["initial"])
        lam[:, -1] = -last[:, -1] - 0.5 * hN * lgl_weights(nN)[-1] * hx(N - 1, mapped["final"])
    return lam, mapped
