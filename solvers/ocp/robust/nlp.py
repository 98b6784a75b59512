"""The robust phase as a multiple-shooting NLP: the augmented functions of :mod:`solvers.ocp.robust.cadet`
transcribed by the deterministic :class:`solvers.ocp.phase.PhaseNLP`, with this job's numbers (scales,
bounds, constants) and a guess from the deterministic twin's answer.

The mean's bounds and scales are the deterministic phase's own (:func:`solvers.ocp.scaling.numbers_of`);
the integral of a Lagrange term starts at zero; the sensitivities start at ``S(0)`` (fixed) and are free
elsewhere, each entry scaled by its largest magnitude along the twin's controls (their sizes differ by
orders of magnitude between a position and an angle).  Rows: the defects (mean and sensitivities), per
node the path rows (``mu`` in the constraint's bounds, or ``mu + k sigma <= upper`` and
``mu - k sigma >= lower``), the boundary rows likewise.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from solvers.ocp.guess import guess_of
from solvers.ocp.phase import PhaseNLP, ms_interval, positive_scale
from solvers.ocp.problem import OcpProblem
from solvers.ocp.robust.cadet import EPS_FRACTION, Layout, RobustFunctions, layout_of
from solvers.ocp.robust.model import RobustSpec
from solvers.ocp.scaling import numbers_of
from solvers.ocp.symbolic import functions_of

INF = np.inf


@dataclass
class Design:
    """One answer of the robust NLP in physical units: times, controls, the augmented states."""

    tf: float
    theta: np.ndarray
    Z: np.ndarray            # (nz, N): mean, integral, sensitivities at the nodes
    U: np.ndarray            # (nu, Nu) as transcribed
    t_nodes: np.ndarray


class RobustNLP:
    """The robust NLP of a problem posed as one phase (module docstring)."""

    def __init__(self, problem: OcpProblem, rob: RobustSpec, *, ipopt: dict | None = None):
        if not problem.single:
            raise ValueError("robust design of several phases is not done yet")
        self.problem, self.rob = problem, rob
        self.php = php = problem.phases[0].problem
        if php.phase.transcription.method != "multiple_shooting":
            raise ValueError("robust design is transcribed by multiple shooting only (LGL is not done yet)")
        fns = functions_of(php)
        self.lay: Layout = layout_of(problem, rob, fns)
        self.rf = RobustFunctions(fns, self.lay)
        structure = ("robust", php.structure(), self.lay)
        self.nlp = PhaseNLP(php, self.rf.fns, ipopt=ipopt, structure=structure)
        self.det = PhaseNLP(php, fns, build=False)
        self.grid = self.nlp.grid
        cnames = [n for n, _ in problem.constants]
        self.c = np.array([v for _, v in problem.constants], float)
        for p in rob.parameters:
            self.c[cnames.index(p.name)] = p.mean        # the design flies the mean
        self.sigma_s = np.array([p.sigma for p in rob.parameters], float)
        self.sigma_0 = np.array([s.sigma for s in rob.initial], float)

    # -- the guess: the twin's answer with its sensitivities ---------------------------------------
    def interval(self, substeps: int | None = None):
        g = self.grid
        grid = SimpleNamespace(substeps=substeps or g.substeps, control=g.control)
        return ms_interval(self.rf.fns, grid)  # type: ignore[arg-type]

    def propagate(self, *, tf: float, theta, X0: np.ndarray | None, U: np.ndarray,
                  X: np.ndarray | None = None, substeps: int | None = None) -> np.ndarray:
        """The augmented state at the nodes along controls ``U``: from the mean nodes ``X`` when given
        (each interval from its own node, the twin's guess), else one flight from ``X0``."""
        g, rf = self.grid, self.rf
        F = self.interval(substeps)
        t0 = self.php.phase.time.initial
        t = t0 + (tf - t0) * g.tau()
        N = g.n_nodes
        c_aug = self.constants(0.0, 0.0, self.eps_default())
        x0 = X[:, 0] if X is not None else X0
        z = np.concatenate([x0, np.zeros(rf.lay.nq), rf.initial_sensitivity(self.sigma_0).ravel(order="F")])
        Z = np.zeros((z.size, N))
        Z[:, 0] = z
        Ucols = U.shape[1]
        for i in range(N - 1):
            if X is not None:
                z = np.concatenate([X[:, i], Z[rf.base.nx:, i]])
            ua = U[:, min(i, Ucols - 1)]
            ub = U[:, min(i + 1, Ucols - 1)] if g.control == "linear" else ua
            ze, _ = F(z, ua, ub, t[i], t[i + 1] - t[i], theta, c_aug, t0, tf)
            z = np.asarray(ze, float).ravel()
            Z[:, i + 1] = z
        return Z

    # -- numbers -----------------------------------------------------------------------------------
    def eps_default(self) -> np.ndarray:
        ph = self.php.phase
        scales = [positive_scale(c.lower, c.upper) for c in (*ph.path, *ph.boundary)]
        return EPS_FRACTION * np.array([*scales, self.objective_scale], float)

    objective_scale = 1.0

    def constants(self, k: float, k_c: float, eps: np.ndarray) -> np.ndarray:
        return self.rf.constants(self.c, self.sigma_s, k, k_c, eps)

    def place(self, *, det_warm: dict, k: float, k_c: float) -> dict:
        """Start, bounds and parameters of one solve, from the twin's answer ``det_warm`` (a phase block)."""
        php, g, rf, lay = self.php, self.grid, self.rf, self.lay
        ph = php.phase
        tf, theta, X, U = guess_of(php, g, det_warm)
        num = numbers_of(php, self.det, tf)
        self.objective_scale = max(abs(float(det_warm.get("objective", 1.0) or 1.0)), 1e-12)
        Z = self.propagate(tf=tf, theta=theta, X0=None, U=U, X=X)
        N, nx, n = g.n_nodes, rf.base.nx, rf.n
        nw = lay.r0 + lay.ns
        S_all = Z[n:].reshape(n, nw, N, order="F")
        S_scale = np.max(np.abs(S_all), axis=2)
        row_max = np.max(S_scale, axis=1, keepdims=True)
        S_scale = np.maximum(S_scale, np.maximum(1e-3 * row_max, 1e-12))
        q_scale = np.array([positive_scale(float(np.max(np.abs(Z[nx])))) if lay.nq else 1.0][:lay.nq])
        xs_aug = np.concatenate([num.x_scale, q_scale, S_scale.ravel(order="F")])
        # bounds of the mean from the deterministic numbers, unpacked
        i0 = 1 + rf.base.ntheta
        Xlb = num.lbz[i0:i0 + nx * N].reshape(nx, N, order="F") * num.x_scale[:, None]
        Xub = num.ubz[i0:i0 + nx * N].reshape(nx, N, order="F") * num.x_scale[:, None]
        nz = rf.cad.layout.nz
        Zlb, Zub = np.full((nz, N), -INF), np.full((nz, N), INF)
        Zlb[:nx], Zub[:nx] = Xlb, Xub
        Zlb[nx:, 0] = Zub[nx:, 0] = Z[nx:, 0]
        jU = i0 + nx * N
        Ulb = num.lbz[jU:].reshape(rf.base.nu, -1, order="F") * num.u_scale[:, None]
        Uub = num.ubz[jU:].reshape(rf.base.nu, -1, order="F") * num.u_scale[:, None]
        ts, ths, us = num.t_scale, num.theta_scale, num.u_scale

        def pack(tf_, th_, Z_, U_):
            return np.concatenate([[tf_ / ts], np.asarray(th_, float) / ths,
                                   (Z_ / xs_aug[:, None]).ravel(order="F"), (U_ / us[:, None]).ravel(order="F")])

        tf_lb, tf_ub = num.lbz[0] * ts, num.ubz[0] * ts
        th_lb, th_ub = num.lbz[1:i0] * ths, num.ubz[1:i0] * ths
        path_rows, path_lo, path_hi = self._rows(ph.path, lay.robust_path)
        bnd_rows, bnd_lo, bnd_hi = self._rows(ph.boundary, lay.robust_boundary)
        eps = self.eps_default()
        p = np.concatenate([self.constants(k, k_c, eps), [ph.time.initial], xs_aug, us, [ts], ths, path_rows, bnd_rows,
                            [1.0]])
        lbg, ubg = [], []
        for name, rows in self.nlp.layout:
            if name == "defects":
                lbg.append(np.zeros(rows))
                ubg.append(np.zeros(rows))
            elif name == "path":
                lbg.append(np.tile(path_lo / path_rows, N))
                ubg.append(np.tile(path_hi / path_rows, N))
            else:
                lbg.append(bnd_lo / bnd_rows)
                ubg.append(bnd_hi / bnd_rows)
        lbz, ubz = pack(tf_lb, th_lb, Zlb, Ulb), pack(tf_ub, th_ub, Zub, Uub)
        z0 = np.clip(pack(tf, theta, Z, U), lbz, ubz)
        return {"z0": z0, "lbz": lbz, "ubz": ubz, "lbg": np.concatenate(lbg), "ubg": np.concatenate(ubg), "p": p,
                "xs": xs_aug, "us": us, "ts": ts, "ths": ths}

    @staticmethod
    def _rows(constraints, robust):
        """Scales and bounds of the rows of path or boundary constraints (two per robust one)."""
        sc, lo, hi = [], [], []
        for c, r in zip(constraints, robust):
            s = positive_scale(c.lower, c.upper)
            l_, h_ = (-INF if c.lower is None else c.lower), (INF if c.upper is None else c.upper)
            if r:
                sc += [s, s]
                lo += [-INF, l_]
                hi += [h_, INF]
            else:
                sc.append(s)
                lo.append(l_)
                hi.append(h_)
        return np.array(sc, float), np.array(lo, float), np.array(hi, float)

    def design(self, z: np.ndarray, placed: dict) -> Design:
        """The answer ``z`` in physical units."""
        rf, g = self.rf, self.grid
        nth, nz = rf.base.ntheta, rf.cad.layout.nz
        i = 1 + nth
        j = i + nz * g.n_nodes
        tf = float(z[0]) * placed["ts"]
        theta = z[1:i] * placed["ths"]
        Z = z[i:j].reshape(nz, g.n_nodes, order="F") * placed["xs"][:, None]
        U = z[j:].reshape(rf.base.nu, g.n_controls, order="F") * placed["us"][:, None]
        t0 = self.php.phase.time.initial
        return Design(tf=tf, theta=theta, Z=Z, U=U, t_nodes=t0 + (tf - t0) * g.tau())
