"""Several robust phases as one NLP: the deterministic assembly (:class:`solvers.ocp.trajectory.TrajectoryNLP`)
of the phases' augmented functions, its events element extended by the covariance.

The means link as a deterministic problem's do (time and shared states continuous by default, the
``links``, positive durations).  The sensitivities ``S = dx/dw`` have the same columns in every phase
(``w = [xi (the first phase's initial sigmas, whitened); ds (the uncertain constants)]``: one draw flies
through all phases), and a state linked by continuity carries its row across: ``S_{k+1}(t0)[x] =
S_k(tf)[x]`` (one event row per column), so the covariance at the end of phase ``k`` is the start
covariance of phase ``k + 1`` on the linked states; a link that sets a state ``y`` of the next start from
the previous end (:mod:`solvers.ocp.robust.links`: a renamed state, an affine or any expression map) carries
``S_{k+1}(t0)[y] = -(h_xf S_k(tf) + [0, h_s]) / h_y`` (the covariance ``J P J^T``, ``J`` the link's exact
Jacobian); a state the plan sets at a phase's start has zero sensitivity there (the bounds of
:mod:`solvers.ocp.robust.nlp`).  Times are decision variables of the
open-loop plan, not uncertain: a time link holds for the means only.

The objective is the problem's events Mayer term plus each phase's integral (the augmented phases carry
their integrals as states), its variance ``G Sigma_w G^T`` with ``G = sum_k (dJ/dx0_k S_k(t0) +
dJ/dxf_k S_k(tf)) + dJ/ds`` (CasADi's exact Jacobians of the same events expression), and the NLP
minimises (in the user's sense) ``mean + sign k sigma``.
"""
from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from solvers.ocp.phase import Element
from solvers.ocp.problem import OcpProblem
from solvers.ocp.robust.links import carried_links, link_map
from solvers.ocp.symbolic import to_sx
from solvers.ocp.trajectory import TrajectoryNLP


class RobustTrajectory(TrajectoryNLP):
    """The robust NLP of several phases (module docstring); ``phases``: the
    :class:`solvers.ocp.robust.nlp.RobustPhase` of each phase."""

    def __init__(self, mp: OcpProblem, phases: list, *, ipopt: dict | None = None):
        self.rphases = phases
        self.carried = carried_links(mp)
        self.nw = phases[0].lay.r0 + phases[0].lay.ns
        super().__init__(mp, ipopt=ipopt, functions=[p.rf.fns for p in phases],
                         structure=("robust", mp.structure(), tuple(p.lay for p in phases)))
        if not hasattr(self, "objective_moments"):       # a cached solver: the events were not rebuilt
            self._events()

    def _events(self) -> Element:
        mp, nth = self.mp, len(self.mp.parameters)
        base = super()._events()
        cols, _ = self.event_columns()
        w, P = ca.SX.sym("w", cols.size), ca.SX.sym("p", self.np_)
        rows_base, _ = base.fn(w, P, ca.SX(0))
        b0, rp0 = self.blocks[0], self.rphases[0]
        sp0 = b0.nlp.split_p(P[b0.p_slice.start:b0.p_slice.stop])
        c, sig, k, _k_c, eps = rp0.rf.split_c(sp0["c"])
        lay0 = rp0.lay
        ns, r0 = lay0.ns, lay0.r0
        theta = w[:nth] * sp0["thetas"]
        s = ca.SX.sym("s", ns)
        c_s = rp0.rf.with_s(c, s)
        env = {n: c_s[i] for i, (n, _) in enumerate(mp.constants)}
        env.update({q.name: theta[i] for i, q in enumerate(mp.parameters)})
        ev: dict[tuple, Any] = {}
        mean_syms, mean_vals, S0s, Sfs, ends, plan = [], [], [], [], [], []
        i = nth
        for b, rp in zip(self.blocks, self.rphases):
            f, n, nx = b.nlp.fns, rp.rf.n, rp.rf.base.nx
            sp = b.nlp.split_p(P[b.p_slice.start:b.p_slice.stop])
            t0, tf = w[i] * sp["ts"], w[i + 1] * sp["ts"]
            i += 2
            z0, zf = w[i:i + f.nx] * sp["xs"], w[i + f.nx:i + 2 * f.nx] * sp["xs"]
            i += 2 * f.nx
            u0, uf = w[i:i + f.nu] * sp["us"], w[i + f.nu:i + 2 * f.nu] * sp["us"]
            i += 2 * f.nu
            x0s, xfs = ca.SX.sym(f"x0_{b.name}", n), ca.SX.sym(f"xf_{b.name}", n)
            mean_syms += [x0s, xfs]
            mean_vals += [z0[:n], zf[:n]]
            S0s.append(ca.reshape(z0[n:], n, self.nw))
            Sfs.append(ca.reshape(zf[n:], n, self.nw))
            ends.append((x0s, xfs, nx, rp.lay.nq, sp["xs"], n))
            plan.append((t0, tf, u0, uf, z0[:nx], zf[:nx]))
            ev[("t0", b.name)], ev[("tf", b.name)] = t0, tf
            for j, x in enumerate(b.problem.state_names):
                ev[("initial", x, b.name)], ev[("final", x, b.name)] = x0s[j], xfs[j]
            for j, u in enumerate(b.problem.control_names):
                ev[("initial", u, b.name)], ev[("final", u, b.name)] = u0[j], uf[j]
        J = to_sx(mp.objective.expr, env, {t.name: t for t in mp.tables}, ev) \
            if mp.objective.expr is not None else ca.SX(0)
        for _, xfs, nx, nq, _, _ in ends:
            if nq:
                J = J + xfs[nx]
        G = ca.jacobian(J, s) if ns else ca.SX.zeros(1, 0)
        G = ca.horzcat(ca.SX.zeros(1, r0), G)
        for (x0s, xfs, *_), S0, Sf in zip(ends, S0s, Sfs):
            G = G + ca.mtimes(ca.jacobian(J, x0s), S0) + ca.mtimes(ca.jacobian(J, xfs), Sf)
        mu_s = ca.vertcat(*[c[j] for j in lay0.s_index]) if ns else ca.SX.zeros(0)
        J, G = ca.substitute([J, G], [s, *mean_syms], [mu_s, *mean_vals])
        var = ca.sum2(G[:, :r0] ** 2) + (ca.sum2((G[:, r0:] * sig.T) ** 2) if ns else 0)
        sign = mp.robust.objective_sign if mp.robust is not None else 0.0
        robust = J + sign * k * ca.sqrt(ca.fmax(var, 0) + eps[-1] ** 2) if sign else J
        # the covariance across the default continuity: S_{k+1}(t0)[x] = S_k(tf)[x]
        links = []
        for kk, x in mp.state_links:
            a, b = self.blocks[kk], self.blocks[kk + 1]
            ja, jb = a.problem.state_names.index(x), b.problem.state_names.index(x)
            na = ends[kk][5]
            xs_a = ends[kk][4]
            scale = ca.vertcat(*[xs_a[na + col * na + ja] for col in range(self.nw)])
            links.append((S0s[kk + 1][jb, :].T - Sfs[kk][ja, :].T) / scale)
        # a link that sets a state of the next start (solvers.ocp.robust.links): the implicit function's
        # S_b(t0)[y] = -(h_xf S_a(tf) + [0, h_s]) / h_y, one row per column, scaled by the target's S scale
        for cl in self.carried:
            ia, ib = cl.after - 1, cl.after
            jb = self.blocks[ib].problem.state_names.index(cl.target)
            t0a, tfa, u0a, ufa, _, xfa = plan[ia]
            t0b, tfb, u0b, ufb, x0b, _ = plan[ib]
            _, h_y, h_xf, h_s = link_map(mp, cl)(x0b[jb], xfa, ca.vertcat(u0a, ufa, u0b, ufb),
                                                 ca.vertcat(t0a, tfa, t0b, tfb), theta, c, mu_s)
            carried = ca.mtimes(h_xf, Sfs[ia][:ends[ia][2], :]) + ca.horzcat(ca.SX.zeros(1, r0), h_s)
            nb, xs_b = ends[ib][5], ends[ib][4]
            scale = ca.vertcat(*[xs_b[nb + col * nb + jb] for col in range(self.nw)])
            links.append((S0s[ib][jb, :] + carried / h_y).T / scale)
        rows = ca.vertcat(rows_base, *links)
        self.objective_moments = ca.Function("objective_moments", [w, P], [J, var])
        self.n_sensitivity_links = (len(mp.state_links) + len(self.carried)) * self.nw
        fn = ca.Function("ocp_robust_events", [w, P, ca.SX.sym("k")], [rows, self.sign * robust])
        return Element("events", fn, cols[None, :], np.zeros(1), True)

    def event_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lo, hi, scales = super().event_bounds()
        n = (len(self.mp.state_links) + len(self.carried)) * self.nw
        return np.concatenate([lo, np.zeros(n)]), np.concatenate([hi, np.zeros(n)]), scales
