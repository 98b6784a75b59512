"""One phase of an ``ocp`` problem -> a cached IPOPT NLP: multiple shooting (RK4) or LGL collocation.

Both transcriptions build a compact graph: one SX function for an interval (multiple shooting:
``substeps`` RK4 steps with linear or constant controls, the Lagrange integrand as a quadrature
state; LGL: the integral collocation form of :mod:`solvers.transcription.lgl` on one segment of
``nodes`` nodes; one per node count on a refined mesh) ``map``-ped over the intervals, one SX
function for the path constraints mapped over the nodes, one for the events.  Time is ``t = t0 +
(tf - t0) tau`` with ``tau`` in ``[0, 1]`` split into equal intervals or a refined mesh's
(:class:`solvers.ocp.grid.Grid`; each interval's start and width reach it as its ``k``); ``tf`` is
always a decision variable (fixed by equal bounds when the problem fixes it), so fixed and free
final time share a structure.

What varies between jobs of one structure is an NLP parameter or a bound, never the graph: the
constants, ``t0``, the scales of states, controls, time, parameters and constraints (all taken
from the problem's numbers), and every bound.  The solver is built once per
:meth:`solvers.ocp.problem.PhaseProblem.structure` and cached
(:func:`solvers.transcription.nlp.cached_solver`).

Decision vector (scaled, ``value / scale``): ``[tf, theta (parameters), X (nx x N nodes,
column-major), U (nu x control nodes)]``.  Parameter vector: ``[c, t0, x_scale, u_scale,
t_scale, theta_scale, path_scale, boundary_scale, objective_scale]``.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from solvers.ocp.grid import Grid, grid_of
from solvers.ocp.problem import PhaseProblem
from solvers.ocp.symbolic import PhaseFunctions
from solvers.transcription.lgl import lgl_integration_matrix, lgl_nodes, lgl_weights
from solvers.transcription.nlp import NLPSolver, cached_solver

# IPOPT's Jacobian and Hessian from the elements' SX blocks (block_derivatives) instead of CasADi's
# AD of the MX graph.  Expanding the whole NLP to SX (as Opti with expand=True) was measured
# slower to build: Betts shuttle 9.5 s build + 0.7 s IPOPT against 0.2 s + 1.1 s for the MX graph.
BLOCKS = True


def ms_interval(fns: PhaseFunctions, grid: Grid) -> ca.Function:
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
        x, q = x + incr[:nx], q + incr[nx:, 0]      # [nx:, 0]: 0x1 also when nx == 1 (CasADi)
    return ca.Function("ocp_interval", [xa, ua, ub, ta, h, theta, c, t0, tf], [x, q])


def _lgl_segment(fns: PhaseFunctions, n: int) -> ca.Function:
    """Integral LGL collocation on one segment: (X (nx x n), U (nu x n), ta, h, theta, c, t0, tf)
    -> (defects nx x (n-1), quadrature)."""
    nx, nu = fns.nx, fns.nu
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


@dataclass(frozen=True)
class Element:
    """One kind of term of the NLP, repeated ``count`` times: ``fn(w, p, k) -> (y, f)`` with ``w``
    the instance's decision variables (the columns ``cols[k]`` of ``z``), ``k`` a number per
    instance (interval index or node position), ``y`` its constraint values (the rows
    ``offset + len(y) k ...`` of ``g``) and ``f`` its share of the objective."""

    name: str
    fn: ca.Function
    cols: np.ndarray          # (count, nw) global columns of each instance's w
    kvals: np.ndarray         # (count,) or (count, nk): each instance's k
    has_f: bool = True        # False: its objective share is zero (no Lagrange term)

    @property
    def count(self) -> int:
        return self.cols.shape[0]

    @property
    def ny(self) -> int:
        return int(self.fn.size1_out(0))


class PhaseNLP:
    pack: Callable[..., np.ndarray]  # (tf, theta, X, U) -> scaled z, set by solvers.ocp.scaling.numbers_of

    """A built (or cached) NLP for one phase structure, with the layout to pack and unpack it.

    The NLP is a sum of elements (:class:`Element`: intervals or segments, path nodes, the
    events), each an SX function of its own few variables ``map``-ped over its instances; IPOPT's
    Jacobian and Hessian of the Lagrangian are assembled from the elements' SX Jacobians and
    Hessians (the idea of :mod:`solvers.transcription.blocks`, for any element layout), which is
    2-3x cheaper per iteration than CasADi's forward-over-reverse sweeps through the MX graph.
    """

    def __init__(self, problem: PhaseProblem, fns: PhaseFunctions, *, ipopt: dict | None = None,
                 build: bool = True, structure: tuple | None = None):
        """``build=False``: the layout and the elements only, no solver (a block of the
        problem's NLP of several phases, :mod:`solvers.ocp.trajectory`); ``structure``: the cache key's
        structure when ``fns`` are not the problem's own (the robust phase, :mod:`solvers.ocp.robust`)."""
        self.fns, self.grid = fns, grid_of(problem)
        self.sign = -1.0 if problem.objective.sense == "maximize" else 1.0
        g = self.grid
        self.nz = 1 + fns.ntheta + fns.nx * g.n_nodes + fns.nu * g.n_controls
        self.np_ = fns.nc + 1 + fns.nx + fns.nu + 1 + fns.ntheta + fns.npath + fns.nboundary + 1
        if not build:
            self.solver, self.was_cached = None, False
            self.layout = [(el.name, el.ny * el.count) for el in self.elements() if el.ny]
            return
        key = ("ocp", structure or problem.structure(), BLOCKS, tuple(sorted((ipopt or {}).items())))
        self.solver, self.was_cached = cached_solver(key, lambda: self._build(ipopt or {}))
        self.layout = self.solver.layout

    def split_p(self, p):
        fns = self.fns
        sizes = [("c", fns.nc), ("t0", 1), ("xs", fns.nx), ("us", fns.nu), ("ts", 1),
                 ("thetas", fns.ntheta), ("paths", fns.npath), ("bnds", fns.nboundary), ("objs", 1)]
        out, i = {}, 0
        for name, n in sizes:
            out[name] = p[i:i + n]
            i += n
        return out

    def node_controls(self, U):
        """Controls at the nodes: a constant control's last node repeats the last interval's."""
        if self.grid.n_controls == self.grid.n_nodes:
            return U
        return ca.horzcat(U, U[:, -1]) if not isinstance(U, np.ndarray) else np.hstack([U, U[:, -1:]])

    # -- columns of z -----------------------------------------------------------------------------
    def _x_cols(self, j: int) -> np.ndarray:
        return 1 + self.fns.ntheta + self.fns.nx * j + np.arange(self.fns.nx)

    def _u_cols(self, j: int) -> np.ndarray:
        g = self.grid
        j = min(j, g.n_controls - 1)
        return 1 + self.fns.ntheta + self.fns.nx * g.n_nodes + self.fns.nu * j + np.arange(self.fns.nu)

    def _common_cols(self) -> np.ndarray:
        return np.arange(1 + self.fns.ntheta)

    # -- the elements -----------------------------------------------------------------------------
    def _elements(self) -> list[Element]:
        fns, g = self.fns, self.grid
        nx, nu, nth, m = fns.nx, fns.nu, fns.ntheta, g.intervals
        p = ca.SX.sym("p", self.np_)
        P = self.split_p(p)
        c, t0 = P["c"], P["t0"]
        k = ca.SX.sym("k")
        kab = ca.SX.sym("kab", 2)           # an interval's start and width in tau (any mesh)
        tfz, thz = ca.SX.sym("tfz"), ca.SX.sym("thz", nth)
        tf, theta = tfz * P["ts"], thz * P["thetas"]
        ta, h = t0 + (tf - t0) * kab[0], (tf - t0) * kab[1]
        b = g.bounds()
        kvals = np.column_stack([b[:-1], np.diff(b)])
        objective = self.sign / P["objs"]
        out = []
        if g.method == "multiple_shooting":
            linear = g.control == "linear"
            xa, xb = ca.SX.sym("xa", nx), ca.SX.sym("xb", nx)
            ua, ub = ca.SX.sym("ua", nu), ca.SX.sym("ub", nu)
            xe, q = ms_interval(fns, g)(xa * P["xs"], ua * P["us"], (ub if linear else ua) * P["us"],
                                         ta, h, theta, c, t0, tf)
            w = ca.vertcat(tfz, thz, xa, ua, *([ub] if linear else []), xb)
            f = objective * q if fns.nq else ca.SX(0)
            fn = ca.Function("ocp_interval_el", [w, p, kab], [(xe - xb * P["xs"]) / P["xs"], f])
            cols = [np.concatenate([self._common_cols(), self._x_cols(i), self._u_cols(i),
                                    *([self._u_cols(i + 1)] if linear else []), self._x_cols(i + 1)])
                    for i in range(m)]
            out.append(Element("defects", fn, np.array(cols), kvals, bool(fns.nq)))
        else:
            # One element per node count: a refined mesh mixes degrees (solvers.transcription.refine).
            per, off = g.nodes_per_interval(), g.offsets()
            for n in sorted(set(per.tolist())):
                which = np.flatnonzero(per == n)
                Xs, Us = ca.SX.sym("X", nx, n), ca.SX.sym("U", nu, n)
                d, q = _lgl_segment(fns, n)(Xs * ca.repmat(P["xs"], 1, n), Us * ca.repmat(P["us"], 1, n),
                                            ta, h, theta, c, t0, tf)
                w = ca.vertcat(tfz, thz, ca.vec(Xs), ca.vec(Us))
                f = objective * q if fns.nq else ca.SX(0)
                name = "ocp_segment_el" if len(set(per.tolist())) == 1 else f"ocp_segment{n}_el"
                fn = ca.Function(name, [w, p, kab], [ca.vec(d / ca.repmat(P["xs"], 1, n - 1)), f])
                cols = []
                for i in which:
                    nodes = range(off[i], off[i] + n)
                    cols.append(np.concatenate([self._common_cols(), *[self._x_cols(j) for j in nodes],
                                                *[self._u_cols(j) for j in nodes]]))
                out.append(Element("defects", fn, np.array(cols), kvals[which], bool(fns.nq)))
        xs_, us_ = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
        if fns.npath:
            t = t0 + (tf - t0) * k
            y = fns.path(t, xs_ * P["xs"], us_ * P["us"], theta, c, t0, tf) / P["paths"]
            fn = ca.Function("ocp_path_el", [ca.vertcat(tfz, thz, xs_, us_), p, k], [y, ca.SX(0)])
            cols = [np.concatenate([self._common_cols(), self._x_cols(j), self._u_cols(j)])
                    for j in range(g.n_nodes)]
            out.append(Element("path", fn, np.array(cols), g.tau(), False))
        x0, xN, u0, uN = ca.SX.sym("x0", nx), ca.SX.sym("xN", nx), ca.SX.sym("u0", nu), ca.SX.sym("uN", nu)
        b, mayer = fns.events(t0, tf, x0 * P["xs"], xN * P["xs"], u0 * P["us"], uN * P["us"], theta, c)
        fn = ca.Function("ocp_events_el", [ca.vertcat(tfz, thz, x0, xN, u0, uN), p, k],
                         [b / P["bnds"] if fns.nboundary else ca.SX.zeros(0), objective * mayer])
        ends = np.concatenate([self._common_cols(), self._x_cols(0), self._x_cols(g.n_nodes - 1),
                               self._u_cols(0), self._u_cols(g.n_nodes - 1)])
        out.append(Element("boundary", fn, ends[None, :], np.zeros(1)))
        return out

    def elements(self) -> list[Element]:
        """The phase's elements on its own decision vector (``[tf, theta, X, U]``, scaled)."""
        return self._elements()

    def _build(self, ipopt: dict) -> NLPSolver:
        return solver_of_elements(self._elements(), nz=self.nz, np_=self.np_, name=f"ocp_{self.grid.method}",
                                  ipopt=ipopt)


def solver_of_elements(elements: list[Element], *, nz: int, np_: int, name: str, ipopt: dict) -> NLPSolver:
    """The IPOPT solver of a sum of elements (their constraints stacked in order), its
    ``layout`` the ``(name, rows)`` of each element with constraints."""
    z, p = ca.MX.sym("z", nz), ca.MX.sym("p", np_)
    parts, layout, f = [], [], ca.MX(0)
    for el in elements:
        W = ca.reshape(z[el.cols.ravel().tolist()], el.cols.shape[1], el.count)
        Y, F = el.fn.map(el.count, "serial")(W, p, ca.DM(el.kvals).T)
        if el.has_f:      # else the gradient of f would sweep back through every interval
            f = f + ca.sum2(F)
        if el.ny:
            parts.append(ca.vec(Y))
            layout.append((el.name, el.ny * el.count))
    nlp = {"x": z, "p": p, "f": f, "g": ca.vertcat(*parts)}
    blocks = ElementBlocks(nlp, elements) if BLOCKS else None
    solver = NLPSolver(nlp, name=name, ipopt=ipopt, blocks=blocks)
    solver.layout = layout
    return solver


def _nz(expr: ca.SX) -> ca.SX:
    return ca.sparsity_cast(expr, ca.Sparsity.dense(expr.nnz(), 1))


def _scatter(values: list, rows: list, cols: list, *, shape: tuple[int, int], upper: bool) -> ca.MX:
    """The sparse matrix whose entry (r, c) sums every value mapped there (only r <= c when ``upper``)."""
    r, c = np.concatenate(rows), np.concatenate(cols)
    keep = r <= c if upper else np.ones(r.size, np.bool_)
    nrow = shape[0]
    key = c.astype(np.int64) * nrow + r
    uniq, inv = np.unique(key[keep], return_inverse=True)
    sp = ca.Sparsity.triplet(nrow, shape[1], (uniq % nrow).tolist(), (uniq // nrow).tolist())
    A = ca.DM(ca.Sparsity.triplet(uniq.size, r.size, inv.tolist(), np.flatnonzero(keep).tolist()), 1.0)
    return ca.sparsity_cast(ca.mtimes(A, ca.vertcat(*values)), sp)


class ElementBlocks:
    """IPOPT's Jacobian and Hessian of the Lagrangian assembled from the elements' SX derivatives.

    The interface :class:`solvers.transcription.nlp.NLPSolver` expects of its ``blocks``
    (as :class:`solvers.transcription.blocks.BlockDerivatives` offers for the reentry layout):
    ``functions`` (name -> SX Function, what :mod:`solvers.transcription.jit` compiles when
    enabled) and ``nlpsol_options(nlp, impl)``.
    """

    def __init__(self, nlp: dict, elements: list[Element]):
        self.elements = elements
        self.functions: dict[str, ca.Function] = {}
        self._sparsity: dict[str, ca.Sparsity] = {}
        np_ = int(nlp["p"].numel())
        for el in elements:
            nw = el.cols.shape[1]
            w, ps, k = ca.SX.sym("w", nw), ca.SX.sym("p", np_), ca.SX.sym("k", el.fn.size1_in(2))
            y, f = el.fn(w, ps, k)
            mu, lf = ca.SX.sym("mu", el.ny), ca.SX.sym("lf")
            if el.ny:
                jac = ca.jacobian(y, w)
                name = f"{el.fn.name()}_jac"
                self.functions[name] = ca.Function(name, [w, ps, k], [_nz(jac)])
                self._sparsity[name] = jac.sparsity()
            hess = ca.hessian(ca.dot(mu, y) + (lf * f if el.has_f else 0), w)[0]
            if hess.nnz():
                name = f"{el.fn.name()}_hess"
                self.functions[name] = ca.Function(name, [w, ps, k, mu, lf], [_nz(hess)])
                self._sparsity[name] = hess.sparsity()

    def nlpsol_options(self, nlp: dict, impl: dict | None = None) -> dict:
        fns = {**self.functions, **(impl or {})}
        z, p = nlp["x"], nlp["p"]
        nz, ng = int(z.numel()), int(nlp["g"].numel())
        lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", ng)
        jv, jr, jc, hv, hr, hc = [], [], [], [], [], []
        offset = 0
        for el in self.elements:
            W = ca.reshape(z[el.cols.ravel().tolist()], el.cols.shape[1], el.count)
            K = ca.DM(el.kvals).T
            name = f"{el.fn.name()}_jac"
            if name in fns:
                r, c = self._sparsity[name].get_triplet()
                jv.append(ca.vec(fns[name].map(el.count, "serial")(W, p, K)))
                jr.append((offset + el.ny * np.arange(el.count)[:, None] + np.asarray(r, int)[None, :]).ravel())
                jc.append(el.cols[:, np.asarray(c, int)].ravel())
            name = f"{el.fn.name()}_hess"
            if name in fns:
                r, c = self._sparsity[name].get_triplet()
                Mu = ca.reshape(lam_g[offset:offset + el.ny * el.count], el.ny, el.count)
                hv.append(ca.vec(fns[name].map(el.count, "serial")(W, p, K, Mu, lam_f)))
                hr.append(el.cols[:, np.asarray(r, int)].ravel())
                hc.append(el.cols[:, np.asarray(c, int)].ravel())
            offset += el.ny * el.count
        J = _scatter(jv, jr, jc, shape=(ng, nz), upper=False)
        H = _scatter(hv, hr, hc, shape=(nz, nz), upper=True) if hv else ca.MX(nz, nz)
        jac_g = ca.Function("nlp_jac_g", [z, p], [nlp["g"], J], ["x", "p"], ["g", "jac_g_x"])
        hess = ca.Function("nlp_hess_l", [z, p, lam_f, lam_g], [H], ["x", "p", "lam_f", "lam_g"],
                           ["triu_hess_gamma_x_x"])
        return {"hess_lag": hess, "jac_g": jac_g}


def positive_scale(*values, default: float = 1.0) -> float:
    """The largest finite magnitude among ``values`` (None skipped), or ``default``."""
    mags = [abs(v) for v in values if v is not None and math.isfinite(v) and v != 0.0]
    return max(mags) if mags else default
