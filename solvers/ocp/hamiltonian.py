"""The Hamiltonian of one ``ocp`` phase, ``H = sign L + lambda' f + mu' (c - c_active)``, as CasADi functions
and at the nodes.

``sign`` is -1 for a maximised objective (the costates are those of the objective as minimised), ``L`` the
Lagrange integrand, ``f`` the dynamics, ``c`` the path constraints and ``mu`` their multipliers per unit time
(:mod:`solvers.ocp.costates`), zero where a constraint is inside its bounds.  The path term vanishes
wherever it is not zero-by-multiplier (``c`` sits on the bound ``c_active`` the multiplier's sign names), so
it leaves H's values alone; it enters ``dH/du`` (stationarity on a mixed constraint's arc) and, through the
NLP's own KKT conditions, the costates' dynamics.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np


@dataclass(frozen=True)
class HamiltonianFunctions:
    """``H`` and ``dH/du`` of ``(t, x, u, theta, c, t0, tf, lam, mu)``; ``mu`` multiplies the path constraints
    minus the bounds they are on (``cb``, the last argument)."""

    H: ca.Function
    dH_du: ca.Function
    dH_dx: ca.Function
    dpath_du: ca.Function         # the path term's share of dH/du, mu' dc/du
    mixed: np.ndarray             # (npath,) bool: the path constraint names a control
    autonomous: bool              # nothing names t (the dynamics, integrand, path constraints): H is constant


def functions(fns, sign: float) -> HamiltonianFunctions:
    t, x, u = ca.SX.sym("t"), ca.SX.sym("x", fns.nx), ca.SX.sym("u", fns.nu)
    th, cc, s0, sf = ca.SX.sym("th", fns.ntheta), ca.SX.sym("c", fns.nc), ca.SX.sym("t0"), ca.SX.sym("tf")
    lam, mu, cb = ca.SX.sym("lam", fns.nx), ca.SX.sym("mu", fns.npath), ca.SX.sym("cb", fns.npath)
    f = fns.rhs(t, x, u, th, cc, s0, sf)
    H = ca.dot(lam, f[:fns.nx]) + (sign * f[fns.nx] if fns.nq else 0)
    mixed = np.zeros(fns.npath, bool)
    term = ca.SX(0)
    c = fns.path(t, x, u, th, cc, s0, sf)
    if fns.npath:
        term = ca.dot(mu, c - cb)
        J = ca.jacobian(c, u)
        mixed = np.array([J[i, :].nnz() > 0 for i in range(fns.npath)], bool)
    H = H + term
    named = ca.vertcat(f, c)
    args = [t, x, u, th, cc, s0, sf, lam, mu, cb]
    return HamiltonianFunctions(H=ca.Function("ocp_H", args, [H]),
                                dH_du=ca.Function("ocp_dH_du", args, [ca.gradient(H, u)]),
                                dH_dx=ca.Function("ocp_dH_dx", args, [ca.gradient(H, x)]),
                                dpath_du=ca.Function("ocp_dpath_du", args, [ca.gradient(term, u)]), mixed=mixed,
                                autonomous=not any(ca.depends_on(named, v) for v in (t, s0, sf)))


def evaluate(fn: ca.Function, *, t, X, U, att, c, t0: float, lam, mu=None, cb=None) -> np.ndarray:
    """``fn`` (an :class:`HamiltonianFunctions` member) at the columns of ``t, X, U, lam`` (and ``mu``, ``cb``:
    none, zero)."""
    n = np.size(t)
    npath = fn.size1_in(8)
    mu = np.zeros((npath, n)) if mu is None else mu
    cb = np.zeros((npath, n)) if cb is None else cb
    return np.asarray(fn.map(n)(np.reshape(t, (1, n)), X, U, att.theta, c, t0, att.tf, lam, mu, cb))


def node_rates(*, fns, att, U: np.ndarray, t_nodes: np.ndarray, c, t0: float) -> np.ndarray:
    """``(nx + nq, N)``: the dynamics and the Lagrange integrand at the nodes (H's terms, the states' rates)."""
    return np.asarray(fns.rhs.map(t_nodes.size)(t_nodes[None, :], att.X, U, att.theta, c, t0, att.tf))


def nodal(*, fns, sign: float, lam: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, float]:
    """H at the nodes from their :func:`node_rates` ``F`` (the path term is zero there by complementarity), and
    the size of its terms (the largest sum of their magnitudes over the nodes: what a check's error is
    measured against, as H itself may be near 0)."""
    terms = lam * F[:fns.nx]
    H, size = np.sum(terms, axis=0), np.sum(np.abs(terms), axis=0)
    if fns.nq:
        H, size = H + sign * F[fns.nx], size + np.abs(F[fns.nx])
    return H, float(np.max(size, initial=0.0))
