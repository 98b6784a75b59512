"""One phase of an ``ocp`` problem -> a cached IPOPT NLP: multiple shooting (RK4) or LGL collocation.

Both transcriptions build a compact graph: one SX function for an interval (multiple shooting:
``substeps`` RK4 steps with linear or constant controls, the Lagrange integrand as a quadrature
state; LGL: the integral collocation form of :mod:`solvers.transcription.lgl` on one segment of
``nodes`` nodes) ``map``-ped over the intervals, one SX function for the path constraints
mapped over the nodes, one for the events.  Time is ``t = t0 + (tf - t0) tau`` with ``tau`` in
``[0, 1]`` split into equal intervals; ``tf`` is always a decision variable (fixed by equal
bounds when the problem fixes it), so fixed and free final time share a structure.

What varies between jobs of one structure is an NLP parameter or a bound, never the graph: the
constants, ``t0``, the scales of states, controls, time, parameters and constraints (all taken
from the problem's numbers), and every bound.  The solver is built once per
:meth:`solvers.ocp.spec.OcpProblem.structure` and cached
(:func:`solvers.transcription.nlp.cached_solver`).

Decision vector (scaled, ``value / scale``): ``[tf, theta (parameters), X (nx x N nodes,
column-major), U (nu x control nodes)]``.  Parameter vector: ``[c, t0, x_scale, u_scale,
t_scale, theta_scale, path_scale, boundary_scale, objective_scale]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from solvers.ocp.spec import OcpProblem
from solvers.ocp.symbolic import PhaseFunctions
from solvers.transcription.lgl import lgl_integration_matrix, lgl_nodes, lgl_weights
from solvers.transcription.nlp import NLPSolver, cached_solver

EXPAND = False   # True: IPOPT evaluates one SX graph (as Opti with expand=True); measured slower to build
                 # (Betts shuttle 9.5 s build + 0.7 s solve) than the mapped SX blocks in MX (0.2 + 1.1 s)


@dataclass(frozen=True)
class Grid:
    """Where the nodes of one transcription sit in normalized time ``tau``."""

    method: str
    intervals: int
    control: str = "linear"
    substeps: int = 2
    nodes: int = 4

    @property
    def n_nodes(self) -> int:
        m = self.intervals
        return m + 1 if self.method == "multiple_shooting" else m * (self.nodes - 1) + 1

    @property
    def n_controls(self) -> int:
        if self.method == "multiple_shooting" and self.control == "constant":
            return self.intervals
        return self.n_nodes

    def tau(self) -> np.ndarray:
        m = self.intervals
        if self.method == "multiple_shooting":
            return np.linspace(0.0, 1.0, m + 1)
        local = 0.5 * (lgl_nodes(self.nodes) + 1.0)
        tau = [(k + local[:-1]) / m for k in range(m)]
        return np.concatenate(tau + [[1.0]])

    def node_interval(self) -> np.ndarray:
        """The interval each node belongs to (a shared end node: the earlier one)."""
        if self.method == "multiple_shooting":
            return np.minimum(np.arange(self.intervals + 1), self.intervals - 1)
        k = np.arange(self.n_nodes) // (self.nodes - 1)
        return np.minimum(k, self.intervals - 1)

    def node_intervals_both(self) -> tuple[np.ndarray, np.ndarray]:
        """For each node, the intervals on its left and right (equal inside an interval)."""
        left = self.node_interval()
        if self.method == "multiple_shooting":
            idx = np.arange(self.intervals + 1)
            return np.maximum(idx - 1, 0), np.minimum(idx, self.intervals - 1)
        n = self.nodes - 1
        idx = np.arange(self.n_nodes)
        ends = idx % n == 0
        lo = np.where(ends, np.maximum(idx // n - 1, 0), left)
        return lo, np.minimum(left, self.intervals - 1)


def grid_of(problem: OcpProblem) -> Grid:
    tr = problem.transcription
    return Grid(method=tr.method, intervals=tr.intervals, control=tr.control, substeps=tr.substeps,
                nodes=tr.nodes)


def _ms_interval(fns: PhaseFunctions, grid: Grid) -> ca.Function:
    """RK4 over one interval: (xa, ua, ub, ta, h, theta, c, t0, tf) -> (x_end, quadrature)."""
    nx, nu, nq = fns.nx, fns.nu, fns.nq
    xa, ua, ub = ca.SX.sym("xa", nx), ca.SX.sym("ua", nu), ca.SX.sym("ub", nu)
    ta, h = ca.SX.sym("ta"), ca.SX.sym("h")
    theta, c = ca.SX.sym("theta", fns.ntheta), ca.SX.sym("c", fns.nc)
    t0, tf = ca.SX.sym("t0"), ca.SX.sym("tf")
    k = grid.substeps
    dt = h / k

    def u_at(frac):
        return ua + frac * (ub - ua) if grid.control == "linear" else ua

    def f(t, x, u):
        return fns.rhs(t, x, u, theta, c, t0, tf)

    x, q = xa, ca.SX.zeros(nq)
    for j in range(k):
        t = ta + j * dt
        u0, um, u1 = u_at(j / k), u_at((j + 0.5) / k), u_at((j + 1.0) / k)
        k1 = f(t, x, u0)
        k2 = f(t + 0.5 * dt, x + 0.5 * dt * k1[:nx], um)
        k3 = f(t + 0.5 * dt, x + 0.5 * dt * k2[:nx], um)
        k4 = f(t + dt, x + dt * k3[:nx], u1)
        incr = dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        x, q = x + incr[:nx], q + incr[nx:]
    return ca.Function("ocp_interval", [xa, ua, ub, ta, h, theta, c, t0, tf], [x, q])


def _lgl_segment(fns: PhaseFunctions, grid: Grid) -> ca.Function:
    """Integral LGL collocation on one segment: (X (nx x n), U (nu x n), ta, h, theta, c, t0, tf)
    -> (defects nx x (n-1), quadrature)."""
    nx, nu, n = fns.nx, fns.nu, grid.nodes
    X, U = ca.SX.sym("X", nx, n), ca.SX.sym("U", nu, n)
    ta, h = ca.SX.sym("ta"), ca.SX.sym("h")
    theta, c = ca.SX.sym("theta", fns.ntheta), ca.SX.sym("c", fns.nc)
    t0, tf = ca.SX.sym("t0"), ca.SX.sym("tf")
    tau = lgl_nodes(n)
    F = ca.horzcat(*[fns.rhs(ta + 0.5 * (tau[j] + 1.0) * h, X[:, j], U[:, j], theta, c, t0, tf)
                     for j in range(n)])
    A = ca.DM(np.asarray(lgl_integration_matrix(n))[1:, :].T)        # (n, n-1)
    defects = X[:, 1:] - ca.repmat(X[:, 0], 1, n - 1) - 0.5 * h * ca.mtimes(F[:nx, :], A)
    quad = 0.5 * h * ca.mtimes(F[nx:, :], ca.DM(lgl_weights(n))) if fns.nq else ca.SX.zeros(0)
    return ca.Function("ocp_segment", [X, U, ta, h, theta, c, t0, tf], [defects, quad])


class PhaseNLP:
    """A built (or cached) NLP for one phase structure, with the layout to pack and unpack it."""

    def __init__(self, problem: OcpProblem, fns: PhaseFunctions, *, ipopt: dict | None = None):
        self.fns, self.grid = fns, grid_of(problem)
        self.sign = -1.0 if problem.objective.sense == "maximize" else 1.0
        g = self.grid
        self.nz = 1 + fns.ntheta + fns.nx * g.n_nodes + fns.nu * g.n_controls
        self.np_ = fns.nc + 1 + fns.nx + fns.nu + 1 + fns.ntheta + fns.npath + fns.nboundary + 1
        key = ("ocp", problem.structure(), EXPAND, tuple(sorted((ipopt or {}).items())))
        self.solver, self.was_cached = cached_solver(key, lambda: self._build(ipopt or {}))
        self.layout = self.solver.ocp_layout

    def split_p(self, p):
        fns = self.fns
        sizes = [("c", fns.nc), ("t0", 1), ("xs", fns.nx), ("us", fns.nu), ("ts", 1),
                 ("thetas", fns.ntheta), ("paths", fns.npath), ("bnds", fns.nboundary), ("objs", 1)]
        out, i = {}, 0
        for name, n in sizes:
            out[name] = p[i:i + n]
            i += n
        return out

    def split_z(self, z):
        fns, g = self.fns, self.grid
        i = 1 + fns.ntheta
        j = i + fns.nx * g.n_nodes
        return (z[0], z[1:i], ca.reshape(z[i:j], fns.nx, g.n_nodes),
                ca.reshape(z[j:], fns.nu, g.n_controls))

    def node_controls(self, U):
        """Controls at the nodes: a constant control's last node repeats the last interval's."""
        if self.grid.n_controls == self.grid.n_nodes:
            return U
        return ca.horzcat(U, U[:, -1]) if not isinstance(U, np.ndarray) else np.hstack([U, U[:, -1:]])

    def _build(self, ipopt: dict) -> NLPSolver:
        fns, g = self.fns, self.grid
        m, N = g.intervals, g.n_nodes
        z, p = ca.MX.sym("z", self.nz), ca.MX.sym("p", self.np_)
        P = self.split_p(p)
        tfz, thz, Xz, Uz = self.split_z(z)
        c, t0 = P["c"], P["t0"]
        tf = tfz * P["ts"]
        theta = thz * P["thetas"]
        X = Xz * ca.repmat(P["xs"], 1, N)
        U = Uz * ca.repmat(P["us"], 1, g.n_controls)
        h = (tf - t0) / m
        ta = t0 + h * ca.DM(np.arange(m)).T
        parts, layout = [], []

        def add(name, expr):
            parts.append(ca.vec(expr))
            layout.append((name, int(expr.numel())))

        if g.method == "multiple_shooting":
            fmap = _ms_interval(fns, g).map(m, "serial")
            ub = U[:, 1:] if g.control == "linear" else U
            xe, q = fmap(X[:, :m], U[:, :m], ub, ta, h, theta, c, t0, tf)
            add("defects", (xe - X[:, 1:]) / ca.repmat(P["xs"], 1, m))
        else:
            n = g.nodes
            idx = [k * (n - 1) + j for k in range(m) for j in range(n)]
            fmap = _lgl_segment(fns, g).map(m, "serial")
            d, q = fmap(X[:, idx], U[:, idx], ta, h, theta, c, t0, tf)
            add("defects", d / ca.repmat(P["xs"], 1, m * (n - 1)))
        if fns.npath:
            t_nodes = t0 + (tf - t0) * ca.DM(g.tau()).T
            vals = fns.path.map(N, "serial")(t_nodes, X, self.node_controls(U), theta, c, t0, tf)
            add("path", vals / ca.repmat(P["paths"], 1, N))
        Un = self.node_controls(U)
        b, mayer = fns.events(t0, tf, X[:, 0], X[:, N - 1], Un[:, 0], Un[:, N - 1], theta, c)
        if fns.nboundary:
            add("boundary", b / P["bnds"])
        J = mayer + (ca.sum2(q) if fns.nq else 0)
        nlp = {"x": z, "p": p, "f": self.sign * J / P["objs"], "g": ca.vertcat(*parts)}
        solver = NLPSolver(nlp, name=f"ocp_{g.method}", ipopt=ipopt,
                           casadi_options={"expand": True} if EXPAND else None)
        solver.ocp_layout = layout
        return solver


def positive_scale(*values, default: float = 1.0) -> float:
    """The largest finite magnitude among ``values`` (None skipped), or ``default``."""
    mags = [abs(v) for v in values if v is not None and math.isfinite(v) and v != 0.0]
    return max(mags) if mags else default
