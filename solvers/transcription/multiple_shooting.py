"""Direct multiple shooting with free final time: an optimal-control problem -> a cached IPOPT NLP.

Method of paper 000 (Qu Xiangju 1991, sec. 1.2, after Bock & Plitt 1984): time is normalized,
``t = T tau`` with ``tau in [0, 1]`` and the final time ``T`` a decision variable; ``[0, 1]`` is
split into ``m`` equal intervals; the controls are continuous piecewise-linear functions of their
node values (or piecewise-constant); the state at every node ``s_i`` is a decision variable; each
interval is an initial-value problem whose end must match the next node (``x(tau_{i+1}; s_i, q) =
s_{i+1}``, the matching conditions); terminal conditions are equalities; control bounds are
bounds.  Path constraints are enforced at the nodes (and optionally at interior integrator
substeps), or by the paper's integral penalty ``int max(c, 0)^2 dt <= eps`` (its ``-int min(c,0)^2
>= 0`` with ``c >= 0`` feasible; here ``c <= 0`` is feasible).  The augmented-Lagrangian/DFP solver
of the paper is replaced by IPOPT with exact CasADi derivatives.

The integrator on each interval is classical RK4 with ``substeps`` steps, written once in CasADi SX
as one interval function and ``map``-ped over the intervals (building a 100-interval NLP then costs
a fraction of a second instead of seconds for an unrolled graph).  Everything here is generic in
the state and control dimensions: the deterministic reentry (6 states) and the robust reentry
(mean + covariance, 39 states) share it.  Decision variables are scaled (``x = x_scale * z``) so
IPOPT sees O(1) numbers.

Layout of the decision vector: ``[T / t_scale, S (nx x (m+1), column-major), U (nu x nu_nodes)]``.
Bounds on ``S`` (initial state fixed, terminal equalities, singularity guards) and on ``U`` are
given per solve, as are the parameters ``p`` (vehicle data, limits): only the *structure* is
compiled and cached (:func:`solvers.transcription.nlp.cached_solver`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import casadi as ca
import numpy as np

from solvers.common import ProgressFn, StopFn
from solvers.transcription.blocks import BlockDerivatives
from solvers.transcription.nlp import NLPResult, NLPSolver, cached_solver

# SX in, SX out and MX in, MX out: casadi's types cannot say "the same kind out", so Any
SymFn = Callable[..., Any]


@dataclass(frozen=True)
class PathConstraint:
    """``fn(x, u, p) -> c`` (SX column, physical x/u), feasible when ``c <= 0``; the caller
    normalizes ``c`` to O(1) (e.g. ``q / q_max - 1``).

    ``where``: ``"nodes"``, ``"midpoints"`` (nodes and the middle substep of each interval, exact
    midpoint when ``substeps`` is even) or ``"substeps"`` (nodes and every interior substep).
    ``integral=True`` replaces pointwise enforcement by ``int max(c, 0)^2 dt <= integral_tol``.
    """

    name: str
    fn: SymFn
    size: int = 1
    where: str = "nodes"
    integral: bool = False


@dataclass
class ShootingProblem:
    """The structure of an optimal-control problem; its numbers go to :meth:`Transcription.solve`.

    ``key`` must identify everything the callables compute (they are not hashable in a useful
    way); together with the sizes and options it keys the solver cache.
    """

    key: tuple
    nx: int
    nu: int
    n_params: int
    dynamics: SymFn                       # (x, u, p) -> xdot, physical units, per second
    x_scale: Sequence[float]
    u_scale: Sequence[float]
    t_scale: float
    intervals: int
    control: str = "linear"               # "linear" | "constant"
    substeps: int = 4
    mayer: SymFn | None = None            # (xf, T, p) -> scalar, minimized
    lagrange: SymFn | None = None         # (x, u, p) -> scalar, its integral over t is minimized
    objective_scale: float = 1.0
    path: tuple[PathConstraint, ...] = ()
    integral_tol: float = 1e-6
    terminal: SymFn | None = None         # (xf, p) -> column of extra terminal constraints
    n_terminal: int = 0
    ipopt: dict = field(default_factory=dict)
    # IPOPT's Hessian and constraint Jacobian assembled from per-interval SX blocks
    # (solvers.transcription.blocks) instead of CasADi's AD of the whole graph: cheaper in the
    # virtual machine and small enough to compile where the whole NLP's C is not.
    block_derivatives: bool = False

    def cache_key(self) -> tuple:
        path = tuple((c.name, c.size, c.where, c.integral) for c in self.path)
        return ("multiple_shooting", self.key, self.nx, self.nu, self.n_params,
                tuple(map(float, self.x_scale)), tuple(map(float, self.u_scale)),
                float(self.t_scale), self.intervals, self.control, self.substeps,
                self.mayer is not None, self.lagrange is not None, float(self.objective_scale),
                path, float(self.integral_tol), self.n_terminal,
                tuple(sorted((k, str(v)) for k, v in self.ipopt.items())), self.block_derivatives)


def control_nodes(intervals: int, control: str) -> int:
    return intervals + 1 if control == "linear" else intervals


def control_at(t, t_nodes: np.ndarray, u_nodes: np.ndarray, control: str) -> np.ndarray:
    """The control the transcription defines at times ``t`` (array of shape (nu, len(t))).

    Linear: interpolation between node values; constant: value of the interval's left node.
    """
    t = np.atleast_1d(np.asarray(t, float))
    u_nodes = np.asarray(u_nodes, float)
    if control == "linear":
        return np.vstack([np.interp(t, t_nodes, row) for row in u_nodes])
    m = u_nodes.shape[1]
    idx = np.clip(np.searchsorted(t_nodes, t, side="right") - 1, 0, m - 1)
    return u_nodes[:, idx]


def _rk4_interval(prob: ShootingProblem) -> tuple[ca.Function, list[PathConstraint], list[PathConstraint]]:
    """One interval, scaled in and out: (s, ua, ub, T, p) -> (s_end, lagrange, integrals, inner path)."""
    nx, nu, k, m = prob.nx, prob.nu, prob.substeps, prob.intervals
    xs = ca.DM(np.asarray(prob.x_scale, float))
    us = ca.DM(np.asarray(prob.u_scale, float))
    s = ca.SX.sym("s", nx)
    ua = ca.SX.sym("ua", nu)
    ub = ca.SX.sym("ub", nu)
    tz = ca.SX.sym("T")
    p = ca.SX.sym("p", prob.n_params)
    T = tz * prob.t_scale
    integ = [c for c in prob.path if c.integral]
    inner = [c for c in prob.path if not c.integral and c.where != "nodes"]
    n_int = sum(c.size for c in integ)

    def u_of(frac):
        if prob.control == "linear":
            return (ua + frac * (ub - ua)) * us
        return ua * us

    def rhs(x, u):
        parts = [prob.dynamics(x, u, p)]
        if prob.lagrange is not None:
            parts.append(prob.lagrange(x, u, p))
        if integ:
            parts.append(ca.vertcat(*[ca.fmax(c.fn(x, u, p), 0) ** 2 for c in integ]))
        return ca.vertcat(*parts)

    h = T / (m * k)
    nq = (1 if prob.lagrange is not None else 0) + n_int
    x = s * xs
    q = ca.SX.zeros(nq)
    inner_vals = []
    for j in range(k):
        f0 = j / k
        u0, um, u1 = u_of(f0), u_of(f0 + 0.5 / k), u_of(f0 + 1.0 / k)
        z = ca.vertcat(x, q)
        k1 = rhs(x, u0)
        k2 = rhs(x + 0.5 * h * k1[:nx], um)
        k3 = rhs(x + 0.5 * h * k2[:nx], um)
        k4 = rhs(x + h * k3[:nx], u1)
        z = z + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        x, q = z[:nx], z[nx:]
        if j < k - 1:
            for c in inner:
                if c.where == "substeps" or (c.where == "midpoints" and j + 1 == k // 2):
                    inner_vals.append(c.fn(x, u1, p))
    lag = q[0] if prob.lagrange is not None else ca.SX(0)
    ints = q[nq - n_int:] if n_int else ca.SX.zeros(0)
    inner_out = ca.vertcat(*inner_vals) if inner_vals else ca.SX.zeros(0)
    fun = ca.Function("interval", [s, ua, ub, tz, p], [x / xs, lag, ints, inner_out],
                      ["s", "ua", "ub", "T", "p"], ["s_end", "lagrange", "integrals", "inner"])
    return fun, integ, inner


@dataclass
class ShootingResult:
    tf: float
    t: np.ndarray          # node times (m+1,)
    x: np.ndarray          # (nx, m+1) physical
    u: np.ndarray          # (nu, m+1 or m) physical
    objective: float       # NLP objective (scaled, as minimized)
    nlp: NLPResult
    was_cached: bool

    @property
    def status(self):
        return self.nlp.status


class Transcription:
    """A built (or cached) multiple-shooting NLP for one :class:`ShootingProblem` structure."""

    def __init__(self, prob: ShootingProblem):
        self.prob = prob
        m, nx, nu = prob.intervals, prob.nx, prob.nu
        self.nu_nodes = control_nodes(m, prob.control)
        self.nz = 1 + nx * (m + 1) + nu * self.nu_nodes
        self.solver, self.was_cached = cached_solver(prob.cache_key(), self._build)
        self.ng = self.solver.ng
        self._g_layout = self.solver.layout

    # -- building -----------------------------------------------------------------------
    def _build(self) -> NLPSolver:
        prob = self.prob
        m, nx, nu = prob.intervals, prob.nx, prob.nu
        nun = control_nodes(m, prob.control)
        z = ca.MX.sym("z", 1 + nx * (m + 1) + nu * nun)
        p = ca.MX.sym("p", prob.n_params)
        tz = z[0]
        S = ca.reshape(z[1:1 + nx * (m + 1)], nx, m + 1)
        U = ca.reshape(z[1 + nx * (m + 1):], nu, nun)
        interval, integ, inner = _rk4_interval(prob)
        fmap = interval.map(m, "serial")
        ua = U[:, :m]
        ub = U[:, 1:] if prob.control == "linear" else U
        s_end, lag, ints, inner_vals = fmap(S[:, :m], ua, ub, tz, p)
        g, layout = [], []

        def add(name, expr, lo, hi):
            n = int(expr.numel())
            g.append(ca.vec(expr))
            layout.append((name, n, lo, hi))

        add("matching", s_end - S[:, 1:], 0.0, 0.0)
        node_path = [c for c in prob.path if not c.integral]
        if node_path:
            xs = ca.DM(np.asarray(prob.x_scale, float))
            us = ca.DM(np.asarray(prob.u_scale, float))
            sx = ca.SX.sym("s", nx)
            su = ca.SX.sym("u", nu)
            sp = ca.SX.sym("p", prob.n_params)
            vals = ca.vertcat(*[c.fn(sx * xs, su * us, sp) for c in node_path])
            cnode = ca.Function("node_path", [sx, su, sp], [vals]).map(m + 1, "serial")
            u_at_nodes = U if prob.control == "linear" else ca.horzcat(U, U[:, m - 1])
            add("path_nodes", cnode(S, u_at_nodes, p), -ca.inf, 0.0)
        if inner:
            add("path_inner", inner_vals, -ca.inf, 0.0)
        if integ:
            add("path_integral", ca.sum2(ints), -ca.inf, prob.integral_tol)
        if prob.terminal is not None:
            xf = S[:, m] * ca.DM(np.asarray(prob.x_scale, float))
            add("terminal", prob.terminal(xf, p), None, None)
        J = ca.MX(0)
        if prob.mayer is not None:
            J = J + prob.mayer(S[:, m] * ca.DM(np.asarray(prob.x_scale, float)), tz * prob.t_scale, p)
        if prob.lagrange is not None:
            J = J + ca.sum2(lag)
        nlp = {"x": z, "p": p, "f": J / prob.objective_scale, "g": ca.vertcat(*g)}
        blocks = self._blocks(interval, layout) if prob.block_derivatives else None
        solver = NLPSolver(nlp, name="multiple_shooting", ipopt=prob.ipopt, blocks=blocks)
        solver.layout = layout
        return solver

    def _blocks(self, interval: ca.Function, layout: list) -> BlockDerivatives:
        """The per-block functions of this structure in scaled variables (see blocks.py)."""
        prob = self.prob
        nx, nu = prob.nx, prob.nu
        xs = ca.DM(np.asarray(prob.x_scale, float))
        us = ca.DM(np.asarray(prob.u_scale, float))
        s = ca.SX.sym("s", nx)
        su = ca.SX.sym("u", nu)
        tz = ca.SX.sym("T")
        sp = ca.SX.sym("p", prob.n_params)
        node_path = [c for c in prob.path if not c.integral]
        node = None
        if node_path:
            node = ca.Function("node_path", [s, su, sp],
                               [ca.vertcat(*[c.fn(s * xs, su * us, sp) for c in node_path])])
        mayer = prob.mayer(s * xs, tz * prob.t_scale, sp) if prob.mayer is not None else ca.SX(0)
        term = prob.terminal(s * xs, sp) if prob.terminal is not None else ca.SX.zeros(0)
        final = ca.Function("final", [s, tz, sp], [mayer, term])
        return BlockDerivatives(nx=nx, nu=nu, n_params=prob.n_params, intervals=prob.intervals,
                                control=prob.control, interval=interval, node=node, final=final,
                                has_lagrange=prob.lagrange is not None,
                                objective_scale=prob.objective_scale, layout=layout)

    # -- solving ------------------------------------------------------------------------
    def pack(self, tf: float, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        prob = self.prob
        xs = np.asarray(prob.x_scale, float)[:, None]
        us = np.asarray(prob.u_scale, float)[:, None]
        return np.concatenate([[tf / prob.t_scale], (np.asarray(x) / xs).ravel(order="F"),
                               (np.asarray(u) / us).ravel(order="F")])

    def unpack(self, z: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        prob = self.prob
        m, nx, nu = prob.intervals, prob.nx, prob.nu
        xs = np.asarray(prob.x_scale, float)[:, None]
        us = np.asarray(prob.u_scale, float)[:, None]
        tf = float(z[0]) * prob.t_scale
        x = z[1:1 + nx * (m + 1)].reshape((nx, m + 1), order="F") * xs
        u = z[1 + nx * (m + 1):].reshape((nu, self.nu_nodes), order="F") * us
        return tf, x, u

    def constraint_blocks(self, g: np.ndarray) -> dict[str, np.ndarray]:
        out, i = {}, 0
        for name, n, _, _ in self._g_layout:
            out[name] = np.asarray(g[i:i + n])
            i += n
        return out

    def path_upper_bounds(self, margins: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Upper bounds of the pointwise path blocks when constraint ``name`` is tightened by
        ``margins[name][j]`` on interval ``j`` (shape (m,), in the constraint's normalized units:
        0.01 asks ``c <= -0.01``, i.e. 1% under the limit).  A node takes the larger margin of its
        two intervals; interior points take their interval's.  Bounds, not structure: no rebuild.
        """
        prob = self.prob
        m = prob.intervals
        node_path = [c for c in prob.path if not c.integral]

        def margin_of(c):
            return np.zeros(m) if c.name not in margins else np.asarray(margins[c.name], float)

        out = {}
        if node_path:
            rows = []
            for c in node_path:
                mj = margin_of(c)
                node = np.maximum(np.append(mj, 0.0), np.insert(mj, 0, 0.0))
                rows += [node] * c.size
            out["path_nodes"] = -np.vstack(rows).ravel(order="F")
        inner_rows = []
        for j in range(prob.substeps - 1):
            for c in prob.path:
                if not c.integral and (c.where == "substeps" or (c.where == "midpoints"
                                                                 and j + 1 == prob.substeps // 2)):
                    inner_rows += [margin_of(c)] * c.size
        if inner_rows:
            out["path_inner"] = -np.vstack(inner_rows).ravel(order="F")
        return out

    def solve(self, *, p, x_lb, x_ub, u_lb, u_ub, tf_bounds, guess,
              terminal_bounds=None, on_progress: ProgressFn | None = None,
              should_stop: StopFn | None = None, progress_span=(0.0, 1.0),
              expected_iterations: int = 60, path_margins: dict[str, np.ndarray] | None = None,
              warm: "ShootingResult | None" = None) -> ShootingResult:
        """``x_lb/x_ub``: (nx, m+1) physical; ``u_lb/u_ub``: (nu,) or (nu, nodes);
        ``guess = (tf, x (nx, m+1), u (nu, nodes))`` physical.  ``path_margins``: see
        :meth:`path_upper_bounds`.  ``warm``: a previous result of this transcription whose
        multipliers are handed to IPOPT (with its primal point as ``guess``); IPOPT uses them
        only when built with ``warm_start_init_point: yes`` in ``ShootingProblem.ipopt``."""
        prob = self.prob
        m = prob.intervals
        nun = self.nu_nodes
        u_lb = np.broadcast_to(np.asarray(u_lb, float).reshape(prob.nu, -1), (prob.nu, nun))
        u_ub = np.broadcast_to(np.asarray(u_ub, float).reshape(prob.nu, -1), (prob.nu, nun))
        lbz = self.pack(tf_bounds[0], x_lb, u_lb)
        ubz = self.pack(tf_bounds[1], x_ub, u_ub)
        z0 = np.clip(self.pack(*guess), lbz, ubz)
        upper = self.path_upper_bounds(path_margins) if path_margins else {}
        lbg, ubg = [], []
        for name, n, lo, hi in self._g_layout:
            if name == "terminal":
                lo, hi = terminal_bounds
            hi = upper.get(name, hi)
            lbg.append(np.broadcast_to(np.asarray(lo, float), (n,)))
            ubg.append(np.broadcast_to(np.asarray(hi, float), (n,)))
        lam: dict[str, Any] = {} if warm is None else {"lam_x0": warm.nlp.lam_x, "lam_g0": warm.nlp.lam_g}
        res = self.solver.solve(x0=z0, lbx=lbz, ubx=ubz, lbg=np.concatenate(lbg),
                                ubg=np.concatenate(ubg), p=np.asarray(p, float),
                                on_progress=on_progress, should_stop=should_stop,
                                progress_span=progress_span,
                                expected_iterations=expected_iterations, **lam)
        tf, x, u = self.unpack(res.x)
        t = np.linspace(0.0, tf, m + 1)
        return ShootingResult(tf=tf, t=t, x=x, u=u, objective=res.f, nlp=res,
                              was_cached=self.was_cached)
