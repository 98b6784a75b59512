"""The user's phase augmented with its first-order covariance: CADET through the problem's own dynamics.

CADET (Gelb, *Applied Optimal Estimation*, ch. 6; paper 001, eqs. 5-8) in the sensitivity form of
:class:`solvers.uncertainty.cadet.CadetSensitivity`: the mean follows ``f(m, u, mu_s)`` and the
sensitivity ``S = dx/dw`` of the state to ``w = [xi (initial states, whitened); ds (the uncertain
constants)]`` follows ``dS/dt = F_x S + [0, F_s]`` with ``S(0) = [diag(sigma0); 0]``; then
``P_xx = S Sigma_w S^T`` exactly solves the linearised covariance equation ``dP/dt = F P + P F^T``
(the state transition applied to the covariance).  ``F_x``, ``F_s`` are CasADi's exact Jacobians of the
same SX symbols the deterministic NLP uses (:func:`solvers.ocp.symbolic.phase_functions`); no finite
differences.

The user's right-hand side ``f(t, x, u, theta, c, t0, tf)`` enters CADET as ``f(x, v, s)`` with
``v = [u; t; theta; c; t0; tf]`` (everything deterministic, passed through; the constants ``c`` carry
the uncertain ones' means, replaced by ``s``), and a Lagrange integrand is one more state (its
variance is the objective's).  What comes out is a :class:`solvers.ocp.symbolic.PhaseFunctions` of the
augmented state, so the deterministic transcription (:class:`solvers.ocp.phase.PhaseNLP`: RK4 shooting or
LGL collocation, block derivatives) builds the robust NLP unchanged: the variational equations are integrated
by the same RK4 steps as the mean, or collocated at the same LGL nodes.  Its constants are ``[c; sigma_s; k; k_c; eps]`` (``k`` of the objective,
``k_c`` of the constraints: the Monte Carlo's rounds raise the latter alone); its path rows per constraint
are ``mu`` (a constraint not named robust) or ``mu + k sigma`` and ``mu - k sigma`` (named), its
boundary rows likewise, and its Mayer term the objective's ``mu + sign k sigma``.  ``sigma`` is
``sqrt(var + eps_j^2)`` with ``eps_j`` a millionth of the constraint's scale (smooth where the
variance vanishes, as at a fixed initial state; conservative by at most ``eps_j``).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from solvers.ocp.problem import OcpProblem
from solvers.ocp.robust.model import RobustSpec
from solvers.ocp.symbolic import PhaseFunctions
from solvers.uncertainty.cadet import CadetSensitivity, CadetSystem

EPS_FRACTION = 1e-6      # eps_j of sigma = sqrt(var + eps_j^2), relative to the constraint's scale


@dataclass(frozen=True)
class Layout:
    """Where the uncertainty sits: the uncertain constants' indices in ``c``, the initial states'
    indices and sigmas, and which path and boundary constraints are held at mean +- k sigma."""

    s_index: tuple[int, ...]          # uncertain constants, in c
    x0_index: tuple[int, ...]         # states with an initial sigma (the first phase's; none in a later one)
    robust_path: tuple[bool, ...]
    robust_boundary: tuple[bool, ...]
    objective_sign: float             # -1, 0, +1
    nq: int
    r0: int                           # whitened initial sigmas: the first columns of S, in every phase
    objective: bool = True            # the phase's events carry the objective (a problem posed as one phase)

    @property
    def ns(self) -> int:
        return len(self.s_index)


def layout_of(problem: OcpProblem, rob: RobustSpec, fns: PhaseFunctions, index: int = 0) -> Layout:
    """Phase ``index``'s layout: the sensitivities' columns ``w = [xi; ds]`` are the problem's, shared by
    every phase (the same draw flies through all of them); the initial sigmas sit on the first phase's
    states; a phase of several carries no objective (the events over all phases do,
    :mod:`solvers.ocp.robust.phases`)."""
    ph = problem.phases[index].problem.phase
    cnames = [n for n, _ in problem.constants]
    by = set(rob.constraints)
    first = problem.phases[0].problem.phase
    return Layout(s_index=tuple(cnames.index(p.name) for p in rob.parameters),
                  x0_index=tuple(first.state_names.index(s.state) for s in rob.initial) if index == 0 else (),
                  robust_path=tuple(c.name in by for c in ph.path),
                  robust_boundary=tuple(c.name in by for c in ph.boundary),
                  objective_sign=rob.objective_sign if problem.single else 0.0, nq=fns.nq, r0=len(rob.initial),
                  objective=problem.single)


class RobustFunctions:
    """The augmented phase (module docstring): ``fns`` for the transcription, ``cad`` for propagation."""

    def __init__(self, fns: PhaseFunctions, lay: Layout):
        self.base, self.lay = fns, lay
        nx, nu, nth, nc, ns = fns.nx, fns.nu, fns.ntheta, fns.nc, lay.ns
        self.n = nx + fns.nq                                  # the mean: states and the integral
        self.nv = nu + 1 + nth + nc + 2                       # v = [u; t; theta; c; t0; tf]
        x, v, s = ca.SX.sym("x", self.n), ca.SX.sym("v", self.nv), ca.SX.sym("s", ns)
        u, t, theta, c, t0, tf = self.split_v(v)
        c_s = self.with_s(c, s)
        f = ca.Function("f_cadet", [x, v, s], [fns.rhs(t, x[:nx], u, theta, c_s, t0, tf)])
        self.cad = CadetSensitivity(f, nx=self.n, nu=self.nv, ns=ns, r0=lay.r0)
        self.n_path = sum(2 if r else 1 for r in lay.robust_path)
        self.n_boundary = sum(2 if r else 1 for r in lay.robust_boundary)
        self.nc_aug = nc + ns + 2 + (fns.npath + fns.nboundary + 1)     # [c; sigma_s; k; k_c; eps]
        self.fns = self._functions()

    # -- pieces ------------------------------------------------------------------------------------
    def split_v(self, v):
        b = self.base
        i = b.nu
        return v[:i], v[i], v[i + 1:i + 1 + b.ntheta], v[i + 1 + b.ntheta:i + 1 + b.ntheta + b.nc], \
            v[self.nv - 2], v[self.nv - 1]

    def with_s(self, c, s):
        """``c`` with the uncertain constants replaced by ``s``."""
        parts = [c[i] for i in range(self.base.nc)]
        for j, i in enumerate(self.lay.s_index):
            parts[i] = s[j]
        return ca.vertcat(*parts) if parts else ca.SX.zeros(0)

    def split_c(self, c_aug):
        """``(c, sigma_s, k, k_c, eps)`` of the augmented constants; eps: path, boundary, objective."""
        b, ns = self.base, self.lay.ns
        c = c_aug[:b.nc]
        sig = c_aug[b.nc:b.nc + ns]
        k, k_c = c_aug[b.nc + ns], c_aug[b.nc + ns + 1]
        eps = c_aug[b.nc + ns + 2:]
        return c, sig, k, k_c, eps

    def theta_cadet(self, c, sig):
        """CADET's ``[mu_s; vec(P_ss)]``: the means are the constants' values, P_ss = diag(sigma^2)."""
        mu = ca.vertcat(*[c[i] for i in self.lay.s_index]) if self.lay.ns else ca.SX.zeros(0)
        P = ca.diag(sig ** 2) if self.lay.ns else ca.SX.zeros(0, 0)
        return ca.vertcat(mu, ca.reshape(P, -1, 1))

    # -- the augmented phase functions -------------------------------------------------------------
    def _functions(self) -> PhaseFunctions:
        b, lay, cad = self.base, self.lay, self.cad
        nz = cad.layout.nz
        t, t0, tf = ca.SX.sym("t"), ca.SX.sym("t0"), ca.SX.sym("tf")
        z, u = ca.SX.sym("z", nz), ca.SX.sym("u", b.nu)
        theta, c_aug = ca.SX.sym("theta", b.ntheta), ca.SX.sym("c", self.nc_aug)
        c, sig, _, k, eps = self.split_c(c_aug)
        th_cad = self.theta_cadet(c, sig)
        v = ca.vertcat(u, t, theta, c, t0, tf)
        args, names = [t, z, u, theta, c_aug, t0, tf], ["t", "x", "u", "theta", "c", "t0", "tf"]
        rhs = ca.Function("robust_rhs", args, [cad.rhs(z, v, th_cad)], names, ["f"])

        # path: moments of each constraint as an output of (x, v, s)
        xs_, vs_, ss_ = ca.SX.sym("x", self.n), ca.SX.sym("v", self.nv), ca.SX.sym("s", lay.ns)
        uu, tt, thh, cc, tt0, ttf = self.split_v(vs_)
        g = b.path(tt, xs_[:b.nx], uu, thh, self.with_s(cc, ss_), tt0, ttf)
        rows = []
        if b.npath:
            mom = cad.output_moments(ca.Function("path_out", [xs_, vs_, ss_], [g]), name="path_moments")
            mu, var = mom(z, v, th_cad)
            for j, robust in enumerate(lay.robust_path):
                if robust:
                    sd = ca.sqrt(ca.fmax(var[j], 0) + eps[j] ** 2)
                    rows += [mu[j] + k * sd, mu[j] - k * sd]
                else:
                    rows.append(mu[j])
        pathf = ca.Function("robust_path", args, [ca.vertcat(*rows) if rows else ca.SX.zeros(0)], names, ["g"])
        named = b.named(t, z[:b.nx], u, theta, c, t0, tf)
        namedf = ca.Function("robust_named", args, [named], names, ["e"])
        events = self._events()
        return PhaseFunctions(rhs=rhs, path=pathf, named=namedf, events=events, nx=nz, nu=b.nu,
                              ntheta=b.ntheta, nc=self.nc_aug, nq=0, npath=self.n_path,
                              nboundary=self.n_boundary)

    def _events(self) -> ca.Function:
        b, lay, cad = self.base, self.lay, self.cad
        nz, nx, ns, r0 = cad.layout.nz, b.nx, lay.ns, lay.r0
        t0, tf = ca.SX.sym("t0"), ca.SX.sym("tf")
        z0, zf = ca.SX.sym("z0", nz), ca.SX.sym("zf", nz)
        u0, uf = ca.SX.sym("u0", b.nu), ca.SX.sym("uf", b.nu)
        theta, c_aug = ca.SX.sym("theta", b.ntheta), ca.SX.sym("c", self.nc_aug)
        c, sig, k, k_c, eps = self.split_c(c_aug)
        # the event functions of deviations: x0, xf and s symbolic, evaluated at the means
        x0s, xfs, ss = ca.SX.sym("x0", self.n), ca.SX.sym("xf", self.n), ca.SX.sym("s", ns)
        bvals, mayer = b.events(t0, tf, x0s[:nx], xfs[:nx], u0, uf, theta, self.with_s(c, ss))
        if lay.nq and lay.objective:
            mayer = mayer + xfs[nx]
        if not lay.objective:
            mayer = ca.SX(0)
        out = ca.vertcat(bvals, mayer)
        J0, Jf, Js = ca.jacobian(out, x0s), ca.jacobian(out, xfs), ca.jacobian(out, ss)
        mu_s = ca.vertcat(*[c[i] for i in lay.s_index]) if ns else ca.SX.zeros(0)
        S0 = ca.reshape(z0[self.n:], self.n, r0 + ns)
        Sf = ca.reshape(zf[self.n:], self.n, r0 + ns)
        sub = [x0s, xfs, ss]
        at = [z0[:self.n], zf[:self.n], mu_s]
        mu, J0, Jf, Js = ca.substitute([out, J0, Jf, Js], sub, at)
        Gw = ca.mtimes(J0, S0) + ca.mtimes(Jf, Sf)         # d(out)/dw
        Gs = Gw[:, r0:] + Js
        var = ca.sum2((Gs * ca.repmat(sig.T, Gs.size1(), 1)) ** 2) if ns else ca.SX.zeros(out.size1())
        if r0:
            var = var + ca.sum2(Gw[:, :r0] ** 2)
        rows = []
        for j, robust in enumerate(lay.robust_boundary):
            if robust:
                sd = ca.sqrt(ca.fmax(var[j], 0) + eps[b.npath + j] ** 2)
                rows += [mu[j] + k_c * sd, mu[j] - k_c * sd]
            else:
                rows.append(mu[j])
        m = out.size1() - 1
        robust_mayer = mu[m] + lay.objective_sign * k * ca.sqrt(ca.fmax(var[m], 0) + eps[-1] ** 2) \
            if lay.objective_sign else mu[m]
        self.objective_moments = ca.Function("objective_moments", [t0, tf, z0, zf, u0, uf, theta, c_aug],
                                             [mu[m], var[m]])
        self.boundary_moments = ca.Function("boundary_moments", [t0, tf, z0, zf, u0, uf, theta, c_aug],
                                            [mu[:m], var[:m]])
        return ca.Function("robust_events", [t0, tf, z0, zf, u0, uf, theta, c_aug],
                           [ca.vertcat(*rows) if rows else ca.SX.zeros(0), robust_mayer],
                           ["t0", "tf", "x0", "xf", "u0", "uf", "theta", "c"], ["b", "mayer"])

    def initial_sensitivity(self, x0_sigma: np.ndarray) -> np.ndarray:
        """``S(0)`` (n x nw): the initial sigmas on their states' rows, zero for the constants."""
        S = np.zeros((self.n, self.lay.r0 + self.lay.ns))
        for j, i in enumerate(self.lay.x0_index):
            S[i, j] = x0_sigma[j]
        return S

    def constants(self, c: np.ndarray, sigma_s: np.ndarray, k: float, k_c: float, eps: np.ndarray) -> np.ndarray:
        return np.concatenate([c, sigma_s, [k, k_c], eps])

    def theta_numbers(self, c: np.ndarray, sigma_s: np.ndarray) -> np.ndarray:
        return CadetSystem.theta(c[list(self.lay.s_index)], np.diag(np.asarray(sigma_s, float) ** 2))


def path_bands(R, design) -> dict[str, dict[str, list]]:
    """CADET's mean and standard deviation of each named robust path constraint at every node of ``design``
    (``R`` a :class:`solvers.ocp.robust.nlp.RobustNLP`), on :func:`state_bands`' time axis (None where a
    phase has not the constraint): the augmented path rows ``mu +- k_c sigma`` evaluated at ``k_c = 1``."""
    named = [n for n in R.rob.constraints if any(n in (c.name for c in P.php.phase.path) for P in R.phases)]
    out: dict[str, dict[str, list]] = {n: {"mean": [], "std": []} for n in named}
    for ip, (P, d) in enumerate(zip(R.phases, design.phases)):
        N = d.Z.shape[1]
        c1 = R.constants(R.rob.k, 1.0, R.eps_default(ip) * 0.0)
        Pv = np.asarray(P.rf.fns.path.map(N)(d.t_nodes[None, :], d.Z, P.det.node_controls(d.U), d.theta, c1,
                                              d.t0, d.tf), float)
        row, rows = 0, {}
        for cn, robust in zip(P.php.phase.path, P.lay.robust_path):
            rows[cn.name] = row if robust else None
            row += 2 if robust else 1
        for n in named:
            r = rows.get(n)
            out[n]["mean"] += [None] * N if r is None else [float(v) for v in 0.5 * (Pv[r] + Pv[r + 1])]
            out[n]["std"] += [None] * N if r is None else [float(v) for v in 0.5 * (Pv[r] - Pv[r + 1])]
    return out


def state_bands(problem, design, sigma_s: np.ndarray) -> dict:
    """CADET's band of a design (``robust.cadet_envelope``, drawn beside the Monte Carlo's): the mean and the
    standard deviation ``sqrt(diag(S Sigma_w S^T))`` of every state at every node, the phases one after
    another on one time axis (None where a phase has not the state); the design's sigmas (the Monte Carlo
    may fly them times ``sigma_factor``)."""
    names = list(dict.fromkeys(x for ph in problem.phases for x in ph.problem.phase.state_names))
    nw = len(problem.robust.initial) + sigma_s.size
    weight = np.concatenate([np.ones(len(problem.robust.initial)), sigma_s ** 2])
    t: list[float] = []
    bands: dict[str, dict[str, list]] = {x: {"mean": [], "std": []} for x in names}
    for named, d in zip(problem.phases, design.phases):
        own = named.problem.phase.state_names
        N = d.Z.shape[1]
        n = d.Z.shape[0] // (1 + nw)
        S = d.Z[n:].reshape(n, nw, N, order="F")
        std = np.sqrt(np.einsum("inj,n->ij", S ** 2, weight))
        t += [float(v) for v in d.t_nodes]
        for x in names:
            i = own.index(x) if x in own else None
            bands[x]["mean"] += [None] * N if i is None else [float(v) for v in d.Z[i]]
            bands[x]["std"] += [None] * N if i is None else [float(v) for v in std[i]]
    return {"t": t, "states": bands}
