"""CADET: mean and covariance propagation through nonlinear dynamics with uncertain constant parameters.

Covariance analysis describing function technique (Gelb, *Applied Optimal
Estimation*, ch. 6; used for robust reentry design in paper 001, its eqs. 5-8
and appendix A).  For Gaussian states the describing function of ``f`` is
``E[df/dz]``; evaluated at the mean this gives the first-order equations

    dm/dt = f(m, u, mu_s)  [+ 0.5 tr(H_i P) per component, second order]
    dP/dt = F P + P F^T

on the augmented state ``z = [x; s]`` with ``ds/dt = 0``.  Because ``s`` is
constant, ``P_ss`` never changes and only ``P_xx`` (symmetric, stored as its
upper triangle) and the cross-covariance ``P_xs`` evolve:

    dP_xx/dt = F_x P_xx + F_s P_sx + (F_x P_xx + F_s P_sx)^T
    dP_xs/dt = F_x P_xs + F_s P_ss

For 6 states and 2 parameters that is 6 + 21 + 12 = 39 ODEs instead of
6 + 64.  Everything is built as CasADi SX so the NLP that uses it gets exact
derivatives; one RK4 interval function is built once and ``map``-ped.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np


def triu_indices(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Row/column indices of the packed upper triangle (row-major), the storage order of P_xx."""
    return np.triu_indices(n)


def _sym_from_triu(v, n: int):
    """Symmetric SX matrix from its packed upper triangle."""
    M = ca.SX.zeros(n, n)
    rows, cols = triu_indices(n)
    for k, (i, j) in enumerate(zip(rows, cols)):
        M[i, j] = v[k]
        M[j, i] = v[k]
    return M


def mean_rate_and_jacobians(f, m, u, mu_s, P_xx, P_xs, P_ss, *, second_order: bool):
    """CADET's mean rate ``f(m, u, mu_s)`` (+ ``0.5 tr(H_i P)`` if ``second_order``)
    and the Jacobians ``F_x``, ``F_s`` at the mean, shared by both storage forms.

    The P_ss block matters in the correction because f is nonlinear in s through
    products like (1 + s) * rho * v^2.
    """
    nx, ns = int(m.numel()), int(mu_s.numel())
    xs = ca.SX.sym("x", nx)
    ss = ca.SX.sym("s", ns)
    fx = f(xs, u, ss)
    jac = ca.Function("F", [xs, u, ss], [ca.jacobian(fx, xs), ca.jacobian(fx, ss)])
    F_x, F_s = jac(m, u, mu_s)
    mdot = f(m, u, mu_s)
    if second_order:
        zaug = ca.vertcat(xs, ss)
        P = ca.blockcat([[P_xx, P_xs], [P_xs.T, P_ss]])
        corr = []
        for i in range(nx):
            H = ca.Function("H", [xs, u, ss], [ca.hessian(fx[i], zaug)[0]])
            corr.append(0.5 * ca.trace(ca.mtimes(H(m, u, mu_s), P)))
        mdot = mdot + ca.vertcat(*corr)
    return mdot, F_x, F_s


@dataclass(frozen=True)
class CadetLayout:
    """Where mean, P_xx (upper triangle) and P_xs sit in the packed augmented vector."""

    nx: int
    ns: int

    @property
    def n_pxx(self) -> int:
        return self.nx * (self.nx + 1) // 2

    @property
    def n_pxs(self) -> int:
        return self.nx * self.ns

    @property
    def nz(self) -> int:
        return self.nx + self.n_pxx + self.n_pxs

    def pack(self, m, P_xx, P_xs) -> np.ndarray:
        """Packed vector(s) from mean(s) ``m`` (nx[,N]), ``P_xx`` (nx,nx[,N]) and ``P_xs`` (nx,ns[,N])."""
        m = np.asarray(m, float)
        P_xx = np.asarray(P_xx, float)
        P_xs = np.asarray(P_xs, float)
        rows, cols = triu_indices(self.nx)
        # P_xs is stored column-major (CasADi's order) so reshape agrees on both sides.
        pxs = P_xs.reshape((self.nx * self.ns,) + P_xs.shape[2:], order="F")
        return np.concatenate([m, P_xx[rows, cols], pxs], axis=0)

    def unpack(self, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(m, P_xx, P_xs)`` from packed vector(s) ``z`` of shape (nz,) or (nz, N)."""
        z = np.asarray(z, float)
        nx, ns = self.nx, self.ns
        tail = z.shape[1:]
        m = z[:nx]
        v = z[nx:nx + self.n_pxx]
        P_xx = np.zeros((nx, nx) + tail)
        rows, cols = triu_indices(nx)
        P_xx[rows, cols] = v
        P_xx[cols, rows] = v
        P_xs = z[nx + self.n_pxx:].reshape((nx, ns) + tail, order="F")
        return m, P_xx, P_xs

    def scale(self, x_scale, s_scale) -> np.ndarray:
        """Per-entry scale of the packed vector: variances scale with the products of state scales.

        ``x_scale`` is a typical magnitude of each state's *deviation* (a sigma scale),
        ``s_scale`` the same for each parameter; the mean uses ``x_scale`` of the
        caller's mean scaling passed separately (see :meth:`scale_with_mean`).
        """
        return self.scale_with_mean(x_scale, x_scale, s_scale)

    def scale_with_mean(self, mean_scale, sigma_scale, s_scale) -> np.ndarray:
        mean_scale = np.asarray(mean_scale, float)
        sx = np.asarray(sigma_scale, float)
        ss = np.asarray(s_scale, float)
        rows, cols = triu_indices(self.nx)
        pxx = sx[rows] * sx[cols]
        pxs = np.outer(sx, ss).reshape(-1, order="F")
        return np.concatenate([mean_scale, pxx, pxs])


class CadetSystem:
    """CADET equations for ``dx/dt = f(x, u, s)`` with constant uncertain ``s ~ N(mu_s, P_ss)``.

    ``f`` is a CasADi Function ``(x[nx], u[nu], s[ns]) -> xdot[nx]`` that accepts SX.
    Functions built here take ``theta = [mu_s; vec(P_ss)]`` (column-major) as the
    parameter vector so the uncertainty can be an NLP parameter instead of part of
    the cached structure.
    """

    def __init__(self, f: ca.Function, *, nx: int, nu: int, ns: int, second_order: bool = False):
        self.f = f
        self.nx, self.nu, self.ns = nx, nu, ns
        self.second_order = second_order
        self.layout = CadetLayout(nx, ns)
        self.n_theta = ns + ns * ns
        self.rhs = self._build_rhs()

    # -- the continuous equations -------------------------------------------------
    def _build_rhs(self) -> ca.Function:
        nx, nu, ns, L = self.nx, self.nu, self.ns, self.layout
        z = ca.SX.sym("z", L.nz)
        u = ca.SX.sym("u", nu)
        theta = ca.SX.sym("theta", self.n_theta)
        m = z[:nx]
        P_xx = _sym_from_triu(z[nx:nx + L.n_pxx], nx)
        P_xs = ca.reshape(z[nx + L.n_pxx:], nx, ns)
        mu_s = theta[:ns]
        P_ss = ca.reshape(theta[ns:], ns, ns)

        mdot, F_x, F_s = mean_rate_and_jacobians(self.f, m, u, mu_s, P_xx, P_xs, P_ss,
                                                 second_order=self.second_order)

        A = ca.mtimes(F_x, P_xx) + ca.mtimes(F_s, P_xs.T)
        Pxx_dot = A + A.T
        Pxs_dot = ca.mtimes(F_x, P_xs) + ca.mtimes(F_s, P_ss)
        rows, cols = triu_indices(nx)
        pxx_dot = ca.vertcat(*[Pxx_dot[int(i), int(j)] for i, j in zip(rows, cols)])
        zdot = ca.vertcat(mdot, pxx_dot, ca.reshape(Pxs_dot, nx * ns, 1))
        return ca.Function("cadet_rhs", [z, u, theta], [zdot], ["z", "u", "theta"], ["zdot"])

    @staticmethod
    def theta(mu_s, P_ss) -> np.ndarray:
        """Parameter vector ``[mu_s; vec(P_ss)]`` in the order the built functions expect."""
        mu_s = np.atleast_1d(np.asarray(mu_s, float))
        P_ss = np.atleast_2d(np.asarray(P_ss, float))
        return np.concatenate([mu_s, P_ss.reshape(-1, order="F")])

    # -- discretisation -----------------------------------------------------------
    def interval(self, substeps: int) -> ca.Function:
        """RK4 over one interval with the control linear between its end values.

        ``(z0, u0, u1, dt, theta) -> (z1, zsub)`` where ``zsub`` (nz x substeps) holds the
        state at the end of each substep (its last column is ``z1``), so a transcription
        can enforce path constraints between nodes.
        """
        L = self.layout
        z0 = ca.SX.sym("z0", L.nz)
        u0 = ca.SX.sym("u0", self.nu)
        u1 = ca.SX.sym("u1", self.nu)
        dt = ca.SX.sym("dt")
        theta = ca.SX.sym("theta", self.n_theta)
        h = dt / substeps
        z = z0
        cols = []
        for k in range(substeps):
            a = k / substeps
            b = (k + 0.5) / substeps
            c = (k + 1) / substeps
            ua = u0 + a * (u1 - u0)
            ub = u0 + b * (u1 - u0)
            uc = u0 + c * (u1 - u0)
            k1 = self.rhs(z, ua, theta)
            k2 = self.rhs(z + 0.5 * h * k1, ub, theta)
            k3 = self.rhs(z + 0.5 * h * k2, ub, theta)
            k4 = self.rhs(z + h * k3, uc, theta)
            z = z + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            cols.append(z)
        return ca.Function("cadet_interval", [z0, u0, u1, dt, theta], [z, ca.horzcat(*cols)],
                           ["z0", "u0", "u1", "dt", "theta"], ["z1", "zsub"])

    # self: Any, since CadetSensitivity shares this method (propagate = CadetSystem.propagate)
    def propagate(self: Any, *, z0, controls, t_nodes, theta, substeps: int = 10) -> tuple[np.ndarray, np.ndarray]:
        """Propagate along given node controls (nu, N+1) at node times (N+1,).

        Returns ``(Z, Zsub)``: the packed state at the nodes (nz, N+1) and at every
        substep end (nz, N*substeps).  The interval function is mapped over nodes
        one interval at a time (the recursion is sequential), so this is for guesses
        and checks, not for the NLP.
        """
        F = self.interval(substeps)
        controls = np.asarray(controls, float).reshape(self.nu, -1)
        t_nodes = np.asarray(t_nodes, float)
        n = t_nodes.size - 1
        Z = np.zeros((self.layout.nz, n + 1))
        Zs = np.zeros((self.layout.nz, n * substeps))
        Z[:, 0] = np.asarray(z0, float)
        for k in range(n):
            z1, zs = F(Z[:, k], controls[:, k], controls[:, k + 1], t_nodes[k + 1] - t_nodes[k], theta)
            Z[:, k + 1] = np.asarray(z1).ravel()
            Zs[:, k * substeps:(k + 1) * substeps] = np.asarray(zs)
        return Z, Zs

    # -- outputs --------------------------------------------------------------------
    def output_moments(self, c: ca.Function, *, name: str = "moments") -> ca.Function:
        """First-order mean and variance of an output ``c(x, u, s)`` (scalar or vector).

        ``(z, u, theta) -> (mu[nc], var[nc])`` with ``var_i = g_i P g_i^T`` and
        ``g_i = dc_i/d[x; s]`` at the mean: what a robust constraint needs without
        any square root.
        """
        nx, ns, L = self.nx, self.ns, self.layout
        z = ca.SX.sym("z", L.nz)
        u = ca.SX.sym("u", self.nu)
        theta = ca.SX.sym("theta", self.n_theta)
        m = z[:nx]
        P_xx = _sym_from_triu(z[nx:nx + L.n_pxx], nx)
        P_xs = ca.reshape(z[nx + L.n_pxx:], nx, ns)
        mu_s = theta[:ns]
        P_ss = ca.reshape(theta[ns:], ns, ns)
        P = ca.blockcat([[P_xx, P_xs], [P_xs.T, P_ss]])
        xs = ca.SX.sym("x", nx)
        ss = ca.SX.sym("s", ns)
        cx = c(xs, u, ss)
        G = ca.Function("G", [xs, u, ss], [cx, ca.jacobian(cx, ca.vertcat(xs, ss))])
        mu, J = G(m, u, mu_s)
        var = ca.sum2(ca.mtimes(J, P) * J)
        return ca.Function(name, [z, u, theta], [mu, var], ["z", "u", "theta"], ["mu", "var"])


# -- sensitivity form ---------------------------------------------------------------------
@dataclass(frozen=True)
class SensitivityLayout:
    """Packed ``[m; vec(S)]`` with ``S = dx/dw`` (nx x nw, column-major), ``w = [x0 directions; s]``."""

    nx: int
    nw: int

    @property
    def nz(self) -> int:
        return self.nx * (1 + self.nw)

    def pack(self, m, S) -> np.ndarray:
        m = np.asarray(m, float)
        S = np.asarray(S, float)
        return np.concatenate([m, S.reshape((self.nx * self.nw,) + S.shape[2:], order="F")], axis=0)

    def unpack(self, z) -> tuple[np.ndarray, np.ndarray]:
        z = np.asarray(z, float)
        return z[:self.nx], z[self.nx:].reshape((self.nx, self.nw) + z.shape[1:], order="F")

    def scale_with_mean(self, mean_scale, sigma_scale, w_scale) -> np.ndarray:
        # S_ij ~ sigma_i / sigma_wj
        S = np.outer(np.asarray(sigma_scale, float), 1.0 / np.asarray(w_scale, float))
        return np.concatenate([np.asarray(mean_scale, float), S.reshape(-1, order="F")])


class CadetSensitivity:
    """First-order CADET in sensitivity form: the same covariance with fewer equations.

    With ``s`` constant and the initial covariance of rank ``r0`` (``P_xx(0) = L0 L0^T``,
    ``P_xs(0) = 0``), the linearized deviation is ``dx(t) = S(t) w`` with
    ``w = [xi; ds] ~ N(0, blockdiag(I, P_ss))`` and ``dS/dt = F_x S + [0, F_s]``, ``S(0) = [L0, 0]``.
    Then ``P_xx = S Sigma_w S^T`` and ``P_xs = S_s P_ss`` solve exactly the Lyapunov
    equations of :class:`CadetSystem`.  For paper 001 (``r0 = 0``, two parameters) that is
    6 + 12 = 18 ODEs instead of 39, which makes every derivative the NLP needs several
    times cheaper; the second-order mean term uses the covariance rebuilt from ``S``.
    ``theta = [mu_s; vec(P_ss)]`` as for :class:`CadetSystem`.
    """

    def __init__(self, f: ca.Function, *, nx: int, nu: int, ns: int, r0: int = 0,
                 second_order: bool = False):
        self.f = f
        self.nx, self.nu, self.ns, self.r0 = nx, nu, ns, r0
        self.second_order = second_order
        self.layout = SensitivityLayout(nx, r0 + ns)
        self.n_theta = ns + ns * ns
        self.rhs = self._build_rhs()

    def _split(self, z, theta):
        nx, ns, r0 = self.nx, self.ns, self.r0
        m = z[:nx]
        S = ca.reshape(z[nx:], nx, r0 + ns)
        mu_s = theta[:ns]
        P_ss = ca.reshape(theta[ns:], ns, ns)
        S0, Ss = S[:, :r0], S[:, r0:]
        P_xs = ca.mtimes(Ss, P_ss)
        P_xx = ca.mtimes(P_xs, Ss.T)
        if r0:
            P_xx = P_xx + ca.mtimes(S0, S0.T)
        return m, S, mu_s, P_ss, P_xx, P_xs

    def _build_rhs(self) -> ca.Function:
        nx, nu, ns, r0, L = self.nx, self.nu, self.ns, self.r0, self.layout
        z = ca.SX.sym("z", L.nz)
        u = ca.SX.sym("u", nu)
        theta = ca.SX.sym("theta", self.n_theta)
        m, S, mu_s, P_ss, P_xx, P_xs = self._split(z, theta)
        mdot, F_x, F_s = mean_rate_and_jacobians(self.f, m, u, mu_s, P_xx, P_xs, P_ss,
                                                 second_order=self.second_order)
        Sdot = ca.mtimes(F_x, S)
        Sdot = ca.horzcat(Sdot[:, :r0], Sdot[:, r0:] + F_s) if r0 else Sdot + F_s
        zdot = ca.vertcat(mdot, ca.reshape(Sdot, nx * (r0 + ns), 1))
        return ca.Function("cadet_sens_rhs", [z, u, theta], [zdot], ["z", "u", "theta"], ["zdot"])

    def initial(self, m0, P0_xx=None) -> np.ndarray:
        """Packed initial vector; ``P0_xx`` must have rank <= r0 (its square root fills S0)."""
        S = np.zeros((self.nx, self.r0 + self.ns))
        if self.r0:
            w, V = np.linalg.eigh(np.asarray(P0_xx, float))
            idx = np.argsort(w)[::-1][:self.r0]
            S[:, :self.r0] = V[:, idx] * np.sqrt(np.maximum(w[idx], 0.0))
        return self.layout.pack(m0, S)

    def covariance(self, z, theta) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(m, P_xx, P_xs)`` from packed vector(s) (nz,) or (nz, N)."""
        theta = np.asarray(theta, float)
        P_ss = theta[self.ns:].reshape(self.ns, self.ns, order="F")
        m, S = self.layout.unpack(z)
        Ss = S[:, self.r0:]
        P_xs = np.einsum("ij...,jk->ik...", Ss, P_ss)
        P_xx = np.einsum("ij...,kj...->ik...", P_xs, Ss)
        if self.r0:
            S0 = S[:, :self.r0]
            P_xx = P_xx + np.einsum("ij...,kj...->ik...", S0, S0)
        return m, P_xx, P_xs

    def variance_of_state(self, z, theta, i: int):
        """Symbolic ``P_xx[i, i]`` of a packed CasADi vector, without forming P_xx."""
        _, S, _, P_ss, _, _ = self._split(z, theta)
        row = S[i, :]
        var = ca.mtimes(ca.mtimes(row[:, self.r0:], P_ss), row[:, self.r0:].T)
        if self.r0:
            var = var + ca.sumsqr(row[:, :self.r0])
        return var

    interval = CadetSystem.interval
    propagate = CadetSystem.propagate

    def output_moments(self, c: ca.Function, *, name: str = "moments") -> ca.Function:
        """As :meth:`CadetSystem.output_moments`; the variance is ``|g S_w|^2`` in whitened form."""
        nx, ns, r0, L = self.nx, self.ns, self.r0, self.layout
        z = ca.SX.sym("z", L.nz)
        u = ca.SX.sym("u", self.nu)
        theta = ca.SX.sym("theta", self.n_theta)
        m, S, mu_s, P_ss, _, _ = self._split(z, theta)
        xs = ca.SX.sym("x", nx)
        ss = ca.SX.sym("s", ns)
        cx = c(xs, u, ss)
        G = ca.Function("G", [xs, u, ss], [cx, ca.jacobian(cx, xs), ca.jacobian(cx, ss)])
        mu, Jx, Js = G(m, u, mu_s)
        # dc = Jx S w + Js ds with w = [xi; ds]: gradient w.r.t. w, then its covariance
        Gw = ca.mtimes(Jx, S)
        Gs = Gw[:, r0:] + Js
        var = ca.sum2(ca.mtimes(Gs, P_ss) * Gs)
        if r0:
            var = var + ca.sum2(Gw[:, :r0] ** 2)
        return ca.Function(name, [z, u, theta], [mu, var], ["z", "u", "theta"], ["mu", "var"])
