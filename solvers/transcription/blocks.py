"""Exact NLP derivatives of a multiple-shooting transcription assembled from per-interval blocks.

Why: CasADi differentiates the NLP graph as a whole.  For the mapped RK4 interval it evaluates
the Hessian of the Lagrangian as forward-over-reverse sweeps through the interval in its virtual
machine and the constraint Jacobian as forward sweeps.  On the robust reentry (18 augmented
states, 23 decision variables per interval) that cost 230 ms (Hessian) and 95 ms (Jacobian) per
IPOPT iteration, two thirds of the solve, and its generated C for the whole NLP was 21 MB, too
big to compile.  The Lagrangian of a multiple-shooting NLP is a sum of per-interval terms, so
its Hessian is a sum of small dense blocks:

* interval ``i``: ``mu_i^T y(w_i)`` with ``w_i = (s_i, ua_i, ub_i, T)`` and ``y`` the interval's
  outputs (end state, interior path values, path integrals, Lagrange term), ``mu_i`` their
  multipliers (and ``lam_f`` for the Lagrange term);
* node ``i``: ``lam_i^T c(s_i, u_i)`` for the pointwise path constraints;
* the final node: ``lam_f * mayer(s_m, T) + lam^T terminal(s_m)``.

Each block's Hessian and Jacobian is written once in CasADi SX (symbolic, exact; the same values
as CasADi's own AD up to rounding), ``map``-ped over the intervals and nodes, and scattered into
the NLP's sparse matrices by constant index maps.  In the virtual machine this is 2.6x cheaper
per iteration (98 + 28 ms on the robust reentry); the block functions are small enough (3.6 +
1 MB of C) to compile with :mod:`solvers.transcription.jit`, which makes them 6 + 3 ms assembled.
Compiling the whole NLP's 21 MB instead was measured too: gcc -O0 22 s and 1.7 GB for 45 + 20 ms,
-Og 71 s CPU and 1.7 GB for 18 + 5.5 ms; the blocks at -Og cost 15-25 s and 0.6 GB.

Used by both reentry kinds (``ShootingProblem.block_derivatives``).  The deterministic reentry
(6 states) gains as much: Betts' max crossrange at 100 intervals, IPOPT 0.73 -> 0.34 s CPU in the
virtual machine (14 iterations either way; integral path limits 58 -> 3.3 s), and compiled a
0.4 MB library instead of the whole NLP's 2.4 MB, 84 -> 63 ms.

The NLP itself (``f``, ``g``, the gradient of ``f``) is unchanged: only ``hess_lag`` and
``jac_g`` are replaced, so the iterates are CasADi's up to rounding.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

# The block functions, by the names their compiled library exports.
NAMES = ("ms_interval_jac", "ms_interval_hess", "ms_node_jac", "ms_node_hess", "ms_final_jac", "ms_final_hess")


def _nz(expr: ca.SX) -> ca.SX:
    """The structural nonzeros of ``expr`` as a dense column (column-major order)."""
    return ca.sparsity_cast(expr, ca.Sparsity.dense(expr.nnz(), 1))


def _triplets(sp: ca.Sparsity) -> tuple[np.ndarray, np.ndarray]:
    r, c = sp.get_triplet()
    return np.asarray(r, int), np.asarray(c, int)


class BlockDerivatives:
    """SX block functions of one transcription and the index maps that assemble them.

    ``interval``: the transcription's interval function ``(s, ua, ub, T, p) -> (s_end, lagrange,
    integrals, inner)`` (scaled variables); ``node``: ``(s, u, p) -> c`` of the pointwise path
    constraints or None; ``final``: ``(s_m, T, p) -> (mayer, terminal)`` in scaled variables.
    ``layout``: the NLP's constraint blocks ``[(name, size, lo, hi)]`` in order.
    """

    def __init__(self, *, nx: int, nu: int, n_params: int, intervals: int, control: str,
                 interval: ca.Function, node: ca.Function | None, final: ca.Function,
                 has_lagrange: bool, objective_scale: float, layout: list):
        self.nx, self.nu, self.m, self.control = nx, nu, intervals, control
        self.nun = intervals + 1 if control == "linear" else intervals
        self.nz = 1 + nx * (intervals + 1) + nu * self.nun
        self.has_lagrange, self.objective_scale = has_lagrange, float(objective_scale)
        self.offsets, i = {}, 0
        for name, n, _, _ in layout:
            self.offsets[name] = (i, n)
            i += n
        self.ng = i
        s = ca.SX.sym("s", nx)
        ua = ca.SX.sym("ua", nu)
        ub = ca.SX.sym("ub", nu)
        tz = ca.SX.sym("T")
        p = ca.SX.sym("p", n_params)
        s_end, lag, ints, inner = interval(s, ua, ub, tz, p)
        self.n_int, self.n_inner = int(ints.numel()), int(inner.numel())
        w = ca.vertcat(s, ua, ub, tz)
        yc = ca.vertcat(s_end, ints, inner)              # the interval's constraint outputs
        y = ca.vertcat(yc, lag) if has_lagrange else yc
        mu = ca.SX.sym("mu", y.numel())
        jac = ca.jacobian(yc, w)
        hess = ca.hessian(ca.dot(mu, y), w)[0]
        fns = {"ms_interval_jac": ca.Function("ms_interval_jac", [s, ua, ub, tz, p], [_nz(jac)]),
               "ms_interval_hess": ca.Function("ms_interval_hess", [s, ua, ub, tz, p, mu], [_nz(hess)])}
        self._sp = {"ms_interval_jac": jac.sparsity(), "ms_interval_hess": hess.sparsity()}
        self.n_node = 0
        if node is not None:
            su = ca.SX.sym("u", nu)
            c = node(s, su, p)
            self.n_node = int(c.numel())
            lam = ca.SX.sym("lam", self.n_node)
            wn = ca.vertcat(s, su)
            jn = ca.jacobian(c, wn)
            hn = ca.hessian(ca.dot(lam, c), wn)[0]
            fns["ms_node_jac"] = ca.Function("ms_node_jac", [s, su, p], [_nz(jn)])
            fns["ms_node_hess"] = ca.Function("ms_node_hess", [s, su, p, lam], [_nz(hn)])
            self._sp.update(ms_node_jac=jn.sparsity(), ms_node_hess=hn.sparsity())
        mayer, term = final(s, tz, p)
        self.n_terminal = int(term.numel())
        lf = ca.SX.sym("lam_f")
        lt = ca.SX.sym("lam_t", self.n_terminal)
        wf = ca.vertcat(s, tz)
        jf = ca.jacobian(term, wf)
        hf = ca.hessian(lf * mayer / self.objective_scale + ca.dot(lt, term), wf)[0]
        fns["ms_final_jac"] = ca.Function("ms_final_jac", [s, tz, p], [_nz(jf)])
        fns["ms_final_hess"] = ca.Function("ms_final_hess", [s, tz, p, lf, lt], [_nz(hf)])
        self._sp.update(ms_final_jac=jf.sparsity(), ms_final_hess=hf.sparsity())
        self.functions = fns

    # -- columns of the decision vector -------------------------------------------------------
    def _cols_s(self, i: int) -> np.ndarray:
        return 1 + self.nx * i + np.arange(self.nx)

    def _cols_u(self, j: int) -> np.ndarray:
        return 1 + self.nx * (self.m + 1) + self.nu * j + np.arange(self.nu)

    def _interval_cols(self, i: int) -> np.ndarray:
        ub = i + 1 if self.control == "linear" else i     # constant control: ub is ua's variable
        return np.concatenate([self._cols_s(i), self._cols_u(i), self._cols_u(ub), [0]])

    def _node_cols(self, i: int) -> np.ndarray:
        return np.concatenate([self._cols_s(i), self._cols_u(min(i, self.nun - 1))])

    def _final_cols(self) -> np.ndarray:
        return np.concatenate([self._cols_s(self.m), [0]])

    def _interval_rows(self, i: int) -> np.ndarray:
        rows = [self.offsets["matching"][0] + self.nx * i + np.arange(self.nx)]
        if self.n_int:
            rows.append(self.offsets["path_integral"][0] + np.arange(self.n_int))
        if self.n_inner:
            rows.append(self.offsets["path_inner"][0] + self.n_inner * i + np.arange(self.n_inner))
        return np.concatenate(rows)

    # -- assembly -------------------------------------------------------------------------------
    def _scatter(self, parts, *, nrow: int, ncol: int, upper: bool):
        """``parts``: ``(values MX column, local rows, local cols)`` with global indices per
        value.  Returns the sparse MX matrix whose entry (r, c) sums the values mapped there
        (only ``r <= c`` when ``upper``)."""
        vals, row_parts, col_parts = [], [], []
        for v, r, c in parts:
            vals.append(v)
            row_parts.append(r)
            col_parts.append(c)
        rows, cols = np.concatenate(row_parts), np.concatenate(col_parts)
        keep = rows <= cols if upper else np.ones(rows.size, np.bool_)
        key = cols * nrow + rows
        uniq, inv = np.unique(key[keep], return_inverse=True)
        sp = ca.Sparsity.triplet(nrow, ncol, list(map(int, uniq % nrow)), list(map(int, uniq // nrow)))
        src = np.flatnonzero(keep)
        A = ca.DM(ca.Sparsity.triplet(uniq.size, rows.size, list(map(int, inv)), list(map(int, src))),
                  1.0)
        return ca.sparsity_cast(ca.mtimes(A, ca.vertcat(*vals)), sp)

    def _local(self, name: str, count: int, rows_of, cols_of, *, symmetric=False):
        """Global row and column of every value of ``count`` instances of block ``name``."""
        r, c = _triplets(self._sp[name])
        R, C = [], []
        for i in range(count):
            rr, cc = rows_of(i), cols_of(i)
            R.append(rr[r])
            C.append(cc[c])
        return np.concatenate(R), np.concatenate(C)

    def nlpsol_options(self, nlp: dict, impl: dict[str, ca.Function] | None = None) -> dict:
        """``{"hess_lag": ..., "jac_g": ...}`` for ``casadi.nlpsol`` on ``nlp`` (the transcription's
        own ``{"x", "p", "f", "g"}``), evaluating the blocks with ``impl`` (compiled externals of the
        same names) or, by default, the SX functions."""
        fns = {**self.functions, **(impl or {})}
        m, nx, nu = self.m, self.nx, self.nu
        z, p = nlp["x"], nlp["p"]
        tz = z[0]
        S = ca.reshape(z[1:1 + nx * (m + 1)], nx, m + 1)
        U = ca.reshape(z[1 + nx * (m + 1):], nu, self.nun)
        ua = U[:, :m]
        ub = U[:, 1:] if self.control == "linear" else U
        u_nodes = U if self.control == "linear" else ca.horzcat(U, U[:, m - 1])

        # Jacobian of g: interval blocks, the -I of the matching conditions, node and final blocks.
        parts = []
        v = fns["ms_interval_jac"].map(m, "serial")(S[:, :m], ua, ub, tz, p)
        parts.append((ca.vec(v), *self._local("ms_interval_jac", m, self._interval_rows, self._interval_cols)))
        mrow = self.offsets["matching"][0] + np.arange(nx * m)
        parts.append((ca.DM.ones(nx * m) * -1.0, mrow, 1 + nx + np.arange(nx * m)))
        if self.n_node:
            v = fns["ms_node_jac"].map(m + 1, "serial")(S, u_nodes, p)
            off = self.offsets["path_nodes"][0]
            parts.append((ca.vec(v), *self._local(
                "ms_node_jac", m + 1, lambda i: off + self.n_node * i + np.arange(self.n_node), self._node_cols)))
        if self.n_terminal:
            v = fns["ms_final_jac"](S[:, m], tz, p)
            off = self.offsets["terminal"][0]
            parts.append((v, *self._local("ms_final_jac", 1, lambda i: off + np.arange(self.n_terminal),
                                          lambda i: self._final_cols())))
        J = self._scatter(parts, nrow=self.ng, ncol=self.nz, upper=False)
        jac_g = ca.Function("nlp_jac_g", [z, p], [nlp["g"], J], ["x", "p"], ["g", "jac_g_x"])

        # Hessian of lam_f f + lam_g^T g (upper triangle).
        lam_f = ca.MX.sym("lam_f")
        lam_g = ca.MX.sym("lam_g", self.ng)

        def block(name):
            off, n = self.offsets[name]
            return lam_g[off:off + n]

        mu = [ca.reshape(block("matching"), nx, m)]
        if self.n_int:
            mu.append(ca.repmat(block("path_integral"), 1, m))
        if self.n_inner:
            mu.append(ca.reshape(block("path_inner"), self.n_inner, m))
        if self.has_lagrange:
            mu.append(ca.repmat(lam_f / self.objective_scale, 1, m))
        parts = []
        v = fns["ms_interval_hess"].map(m, "serial")(S[:, :m], ua, ub, tz, p, ca.vertcat(*mu))
        parts.append((ca.vec(v), *self._local("ms_interval_hess", m, self._interval_cols, self._interval_cols)))
        if self.n_node:
            v = fns["ms_node_hess"].map(m + 1, "serial")(S, u_nodes, p,
                                                          ca.reshape(block("path_nodes"), self.n_node, m + 1))
            parts.append((ca.vec(v), *self._local("ms_node_hess", m + 1, self._node_cols, self._node_cols)))
        lt = block("terminal") if self.n_terminal else ca.MX(0, 1)
        v = fns["ms_final_hess"](S[:, m], tz, p, lam_f, lt)
        parts.append((v, *self._local("ms_final_hess", 1, lambda i: self._final_cols(),
                                      lambda i: self._final_cols())))
        H = self._scatter(parts, nrow=self.nz, ncol=self.nz, upper=True)
        hess = ca.Function("nlp_hess_l", [z, p, lam_f, lam_g], [H],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
        return {"hess_lag": hess, "jac_g": jac_g}
