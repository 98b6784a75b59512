"""The robust problem as an NLP on each phase's own transcription (multiple shooting or LGL): each phase's
augmented functions of :mod:`solvers.ocp.robust.cadet` transcribed by the deterministic
:class:`solvers.ocp.phase.PhaseNLP`, the
phases assembled as the deterministic :class:`solvers.ocp.trajectory.TrajectoryNLP` assembles them (a
problem posed as one phase is the one-phase case; several are linked by
:class:`solvers.ocp.robust.phases.RobustTrajectory`, whose events also carry the covariance across the
links), with this job's numbers (scales, bounds, constants) and a guess from the deterministic twin's answer.

The mean's bounds and scales are the deterministic phase's own (:func:`solvers.ocp.scaling.numbers_of`);
the integral of a Lagrange term starts at zero in every phase; the sensitivities start at ``S(0)`` (fixed) in
the first phase and, in a later one, at the previous phase's final sensitivities on the states linked by
continuity, free (guessed at ``J S``) on those a link sets (:mod:`solvers.ocp.robust.links`), zero on the
others (a state the plan sets at a phase's start is certain); they are free
elsewhere, each entry scaled by its largest magnitude along the twin's controls (their sizes differ by
orders of magnitude between a position and an angle).  Rows: the defects (mean and sensitivities), per
node the path rows (``mu`` in the constraint's bounds, or ``mu + k sigma <= upper`` and
``mu - k sigma >= lower``), the boundary rows likewise, then (several phases) the events.

The transcription treats the augmented state ``[mean; integral; S]`` as any state: RK4 steps of the
variational equations on multiple shooting, and on LGL their collocation at the same nodes with the same
integration matrix as the mean (``S_i = S_0 + (h/2) sum_j A_ij (F_x S_j + F_s)``), which is the collocation
equations of the mean differentiated with respect to the draw ``w``: either way ``S`` is the exact
sensitivity of the transcribed mean, never a finite difference, and ``P = S Sigma_w S^T``.

The NLP is built once per job (:class:`RobustNLP`); a confirmation round that raises the constraints'
``k`` changes a parameter (:meth:`RobustNLP.place`'s ``k_c``), not the graph.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from solvers.ocp.guess import guess_of
from solvers.ocp.phase import PhaseNLP, ms_interval, positive_scale
from solvers.ocp.problem import OcpProblem
from solvers.ocp.robust.links import carried_start
from solvers.ocp.robust.cadet import EPS_FRACTION, Layout, RobustFunctions, layout_of
from solvers.ocp.robust.model import RobustSpec
from solvers.ocp.scaling import numbers_of
from solvers.ocp.symbolic import functions_of
from solvers.ocp.trajectory import TrajectoryNLP

INF = np.inf


@dataclass
class PhaseDesign:
    """One phase of an answer of the robust NLP in physical units: times, controls, the augmented states."""

    t0: float
    tf: float
    theta: np.ndarray
    Z: np.ndarray            # (nz, N): mean, integral, sensitivities at the nodes
    U: np.ndarray            # (nu, Nu) as transcribed
    t_nodes: np.ndarray


@dataclass
class Design:
    """An answer of the robust NLP: its phases (one for a problem posed as one phase)."""

    phases: list[PhaseDesign]

    # the one-phase case reads as its phase
    @property
    def tf(self) -> float:
        return self.phases[-1].tf

    @property
    def theta(self) -> np.ndarray:
        return self.phases[0].theta

    @property
    def Z(self) -> np.ndarray:
        return self.phases[0].Z

    @property
    def U(self) -> np.ndarray:
        return self.phases[0].U

    @property
    def t_nodes(self) -> np.ndarray:
        return self.phases[0].t_nodes


class RobustPhase:
    """One phase of the robust NLP: its augmented functions and its numbers."""

    def __init__(self, problem: OcpProblem, rob: RobustSpec, index: int):
        self.index = index
        self.name = problem.phases[index].name
        self.php = php = problem.phases[index].problem
        self.fns = functions_of(php)
        self.lay: Layout = layout_of(problem, rob, self.fns, index)
        self.rf = RobustFunctions(self.fns, self.lay)
        self.det = PhaseNLP(php, self.fns, build=False)
        self.grid = self.det.grid

    def interval(self, substeps: int | None = None):
        """RK4 of the augmented system over ``substeps`` steps, the control linear between the ends (constant
        for multiple shooting's piecewise-constant controls): the guess's propagation and CADET's check
        between the nodes (on LGL, between two nodes of a segment or two points of its dense grid)."""
        g = self.grid
        grid = SimpleNamespace(substeps=substeps or g.substeps, control="constant" if g.piecewise else "linear")
        return ms_interval(self.rf.fns, grid)  # type: ignore[arg-type]

    def scales(self) -> np.ndarray:
        """Each path and boundary constraint's scale (the rows' and eps's)."""
        ph = self.php.phase
        return np.array([positive_scale(c.lower, c.upper) for c in (*ph.path, *ph.boundary)], float)


class RobustNLP:
    """The robust NLP of a problem (module docstring); ``phases[i]`` its phases."""

    def __init__(self, problem: OcpProblem, rob: RobustSpec, *, ipopt: dict | None = None):
        self.problem, self.rob = problem, rob
        self.phases = [RobustPhase(problem, rob, i) for i in range(len(problem.phases))]
        self.objective_moments = None       # several phases: the objective's (mean, variance) of the events' columns
        if problem.single:
            one = self.phases[0]
            self.nlp: TrajectoryNLP = TrajectoryNLP(problem, ipopt=ipopt, functions=[one.rf.fns],
                                                    structure=("robust", one.php.structure(), one.lay))
        else:
            from solvers.ocp.robust.phases import RobustTrajectory

            several = RobustTrajectory(problem, self.phases, ipopt=ipopt)
            self.nlp, self.objective_moments = several, several.objective_moments
        cnames = [n for n, _ in problem.constants]
        self.c = np.array([v for _, v in problem.constants], float)
        for p in rob.parameters:
            self.c[cnames.index(p.name)] = p.mean        # the design flies the mean
        self.sigma_s = np.array([p.sigma for p in rob.parameters], float)
        self.sigma_0 = np.array([s.sigma for s in rob.initial], float)
        self.objective_scale = 1.0

    # the one-phase case's names (CADET's closed-form tests read them)
    @property
    def rf(self) -> RobustFunctions:
        return self.phases[0].rf

    @property
    def lay(self) -> Layout:
        return self.phases[0].lay

    @property
    def php(self):
        return self.phases[0].php

    @property
    def grid(self):
        return self.phases[0].grid

    def interval(self, substeps: int | None = None, phase: int = 0):
        return self.phases[phase].interval(substeps)

    # -- the guess: the twin's answer with its sensitivities ---------------------------------------
    def propagate(self, *, tf: float, theta, X0: np.ndarray | None, U: np.ndarray,
                  X: np.ndarray | None = None, substeps: int | None = None, phase: int = 0,
                  t0: float | None = None, S0: np.ndarray | None = None) -> np.ndarray:
        """The augmented state of ``phase`` at its nodes along controls ``U``: from the mean nodes ``X`` when
        given (each interval from its own node, the twin's guess), else one flight from ``X0``; the
        sensitivities from ``S0`` (default: the initial sigmas)."""
        P = self.phases[phase]
        g, rf = P.grid, P.rf
        F = P.interval(substeps)
        t0 = P.php.phase.time.initial if t0 is None else t0
        t = t0 + (tf - t0) * g.tau()
        N = g.n_nodes
        c_aug = self.constants(0.0, 0.0, self.eps_default(phase))
        x0 = X[:, 0] if X is not None else X0
        S0 = rf.initial_sensitivity(self.sigma_0) if S0 is None else S0
        z = np.concatenate([x0, np.zeros(rf.lay.nq), S0.ravel(order="F")])
        Z = np.zeros((z.size, N))
        Z[:, 0] = z
        Ucols = U.shape[1]
        for i in range(N - 1):
            if X is not None:
                z = np.concatenate([X[:, i], Z[rf.base.nx:, i]])
            ua = U[:, min(i, Ucols - 1)]
            ub = ua if g.piecewise else U[:, min(i + 1, Ucols - 1)]
            ze, _ = F(z, ua, ub, t[i], t[i + 1] - t[i], theta, c_aug, t0, tf)
            z = np.asarray(ze, float).ravel()
            Z[:, i + 1] = z
        return Z

    # -- numbers -----------------------------------------------------------------------------------
    def eps_default(self, phase: int = 0) -> np.ndarray:
        return EPS_FRACTION * np.array([*self.phases[phase].scales(), self.objective_scale], float)

    def constants(self, k: float, k_c: float, eps: np.ndarray) -> np.ndarray:
        return self.rf.constants(self.c, self.sigma_s, k, k_c, eps)

    def linked_rows(self, phase: int) -> list[tuple[int, int]]:
        """``(row in phase - 1, row in phase)`` of each state the default continuity links into ``phase``."""
        if phase == 0:
            return []
        a, b = self.phases[phase - 1].php.phase, self.phases[phase].php.phase
        return [(a.state_names.index(x), b.state_names.index(x)) for k, x in self.problem.state_links
                if k == phase - 1]

    def place(self, *, det, k: float, k_c: float) -> dict:
        """Start, bounds and parameters of one solve, from the twin's answer ``det`` (an
        :class:`solvers.ocp.solution.OcpSolution`)."""
        nlp = self.nlp
        self.objective_scale = max(abs(float(det.objective or 1.0)), 1e-12)
        z0, lbz, ubz = np.zeros(nlp.nz), np.full(nlp.nz, -INF), np.full(nlp.nz, INF)
        p, lbg, ubg, per = [], [], [], []
        S_end: np.ndarray | None = None
        for i, (P, b) in enumerate(zip(self.phases, nlp.blocks)):
            warm = {**det.phases[i], "parameters": det.parameters}
            one = self._place_phase(P, b.nlp.layout, warm, k=k, k_c=k_c, S_prev=S_end, t0=float(det.phases[i]["t0"]),
                                    prev=det.phases[i - 1] if i else None)
            S_end = one["S_end"]
            lb, ub = one["lbz"], one["ubz"]
            if b.t0_col is not None:       # a phase of several: its window bounds its ends
                ts, t = one["ts"], self.problem.phases[i].time
                lo_t0 = t.initial if t.initial is not None else t.initial_lower
                hi_t0 = t.initial if t.initial is not None else t.initial_upper
                lo_tf = t.final if t.final is not None else t.final_lower
                hi_tf = t.final if t.final is not None else t.final_upper
                lb[0] = -INF if lo_tf is None else lo_tf / ts
                ub[0] = INF if hi_tf is None else hi_tf / ts
                lbz[b.t0_col] = -INF if lo_t0 is None else lo_t0 / ts
                ubz[b.t0_col] = INF if hi_t0 is None else hi_t0 / ts
                z0[b.t0_col] = one["t0"] / ts
            lbz[b.colmap], ubz[b.colmap], z0[b.colmap] = lb, ub, one["z0"]
            p.append(one["p"])
            lbg.append(one["lbg"])
            ubg.append(one["ubg"])
            per.append(one)
        elo, ehi, lscale = nlp.event_bounds()
        return {"z0": np.clip(z0, lbz, ubz), "lbz": lbz, "ubz": ubz, "p": np.concatenate(p + [lscale]),
                "lbg": np.concatenate(lbg + [elo]), "ubg": np.concatenate(ubg + [ehi]), "phases": per}

    def _place_phase(self, P: RobustPhase, layout, warm: dict, *, k: float, k_c: float, S_prev, t0: float,
                     prev: dict | None = None) -> dict:
        php, g, rf, lay = P.php, P.grid, P.rf, P.lay
        ph = php.phase
        tf, theta, X, U = guess_of(php, g, warm)
        num = numbers_of(php, P.det, tf)
        N, nx, n = g.n_nodes, rf.base.nx, rf.n
        nw = lay.r0 + lay.ns
        S0 = None
        fixed = np.ones(n, bool)               # rows of S(0) the problem sets (all, in the first phase)
        if P.index:
            S0 = np.zeros((n, nw))
            for ra, rb in self.linked_rows(P.index):
                S0[rb] = S_prev[ra]
                fixed[rb] = False
            # a state a link sets from the previous end (solvers.ocp.robust.links): free, guessed at J S_prev
            theta = [warm["parameters"][q.name] for q in self.problem.parameters]
            for rb, row in carried_start(self.problem, P.index, S_prev=S_prev, prev=prev, this=warm, theta=theta,
                                         c=self.c, s=self.c[list(lay.s_index)], r0=lay.r0).items():
                S0[rb] = row
                fixed[rb] = False
        Z = self.propagate(tf=tf, theta=theta, X0=None, U=U, X=X, phase=P.index, t0=t0, S0=S0)
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
        Zlb[nx:n, 0] = Zub[nx:n, 0] = Z[nx:n, 0]                   # the integral starts at zero
        S_fixed = np.repeat(fixed[:, None], nw, axis=1).ravel(order="F")
        S0v = Z[n:, 0]
        Zlb[n:, 0] = np.where(S_fixed, S0v, -INF)
        Zub[n:, 0] = np.where(S_fixed, S0v, INF)
        jU = i0 + nx * N
        Ulb = num.lbz[jU:].reshape(rf.base.nu, g.n_controls, order="F") * num.u_scale[:, None]
        Uub = num.ubz[jU:].reshape(rf.base.nu, g.n_controls, order="F") * num.u_scale[:, None]
        ts, ths, us = num.t_scale, num.theta_scale, num.u_scale

        def pack(tf_, th_, Z_, U_):
            return np.concatenate([[tf_ / ts], np.asarray(th_, float) / ths,
                                   (Z_ / xs_aug[:, None]).ravel(order="F"), (U_ / us[:, None]).ravel(order="F")])

        tf_lb, tf_ub = num.lbz[0] * ts, num.ubz[0] * ts
        th_lb, th_ub = num.lbz[1:i0] * ths, num.ubz[1:i0] * ths
        path_rows, path_lo, path_hi = self._rows(ph.path, lay.robust_path)
        bnd_rows, bnd_lo, bnd_hi = self._rows(ph.boundary, lay.robust_boundary)
        eps = self.eps_default(P.index)
        p = np.concatenate([self.constants(k, k_c, eps), [t0], xs_aug, us, [ts], ths, path_rows, bnd_rows, [1.0]])
        lbg, ubg = [], []
        for name, rows in layout:
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
                "xs": xs_aug, "us": us, "ts": ts, "ths": ths, "t0": t0, "S_end": S_all[:, :, -1]}

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
        out = []
        for P, b, one in zip(self.phases, self.nlp.blocks, placed["phases"]):
            rf, g = P.rf, P.grid
            zl = z[b.colmap]
            nth, nz = rf.base.ntheta, rf.cad.layout.nz
            i = 1 + nth
            j = i + nz * g.n_nodes
            tf = float(zl[0]) * one["ts"]
            theta = zl[1:i] * one["ths"]
            Z = zl[i:j].reshape(nz, g.n_nodes, order="F") * one["xs"][:, None]
            U = zl[j:].reshape(rf.base.nu, g.n_controls, order="F") * one["us"][:, None]
            t0 = P.php.phase.time.initial if b.t0_col is None else float(z[b.t0_col]) * one["ts"]
            out.append(PhaseDesign(t0=t0, tf=tf, theta=theta, Z=Z, U=U, t_nodes=t0 + (tf - t0) * g.tau()))
        return Design(out)

    def path_starts(self) -> list[int | None]:
        """Each phase's first path row in the NLP's constraints (None: the phase has no path rows)."""
        out = []
        for b in self.nlp.blocks:
            want = "path" if self.problem.single else f"{b.name}:path"
            start, found = 0, None
            for name, rows in self.nlp.layout:
                if name == want:
                    found = start
                    break
                start += rows
            out.append(found)
        return out
