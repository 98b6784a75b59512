"""CADET covariance propagation on systems whose moments are known in closed form."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.linalg import expm

from solvers.uncertainty.cadet import CadetLayout, CadetSystem


def _linear_oscillator():
    # x = (pos, vel), constant uncertain forcing s: linear in the augmented state,
    # so first-order CADET is exact.
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    s = ca.SX.sym("s", 1)
    k, c = 4.0, 0.3
    xdot = ca.vertcat(x[1], -k * x[0] - c * x[1] + u[0] + s[0])
    A = np.array([[0.0, 1.0, 0.0], [-k, -c, 1.0], [0.0, 0.0, 0.0]])
    B = np.array([[0.0], [1.0], [0.0]])
    return ca.Function("f", [x, u, s], [xdot]), A, B


def _decay():
    x = ca.SX.sym("x", 1)
    u = ca.SX.sym("u", 1)
    s = ca.SX.sym("s", 1)
    return ca.Function("f", [x, u, s], [-s[0] * x[0] + 0.0 * u[0]])


def test_layout_pack_unpack_roundtrip():
    L = CadetLayout(6, 2)
    assert L.nz == 39
    rng = np.random.default_rng(1)
    A = rng.normal(size=(8, 8))
    P = A @ A.T
    m = rng.normal(size=6)
    z = L.pack(m, P[:6, :6], P[:6, 6:])
    m2, Pxx, Pxs = L.unpack(z)
    np.testing.assert_array_equal(m2, m)
    np.testing.assert_allclose(Pxx, P[:6, :6], rtol=0, atol=0)
    np.testing.assert_allclose(Pxs, P[:6, 6:], rtol=0, atol=0)


def test_linear_system_matches_transition_matrix():
    f, A, B = _linear_oscillator()
    sysm = CadetSystem(f, nx=2, nu=1, ns=1)
    P0 = np.diag([0.04, 0.01, 0.25])
    P0[0, 1] = P0[1, 0] = 0.005
    P0[0, 2] = P0[2, 0] = 0.02
    m0 = np.array([1.0, 0.0, 0.5])
    u = 0.7
    tf = 3.0
    theta = CadetSystem.theta([m0[2]], [[P0[2, 2]]])
    z0 = sysm.layout.pack(m0[:2], P0[:2, :2], P0[:2, 2:])
    Z, _ = sysm.propagate(z0=z0, controls=np.full((1, 31), u), t_nodes=np.linspace(0, tf, 31),
                          theta=theta, substeps=8)
    m, Pxx, Pxs = sysm.layout.unpack(Z[:, -1])
    Phi = expm(A * tf)
    # exact mean of the affine system via the augmented exponential
    M = np.zeros((4, 4))
    M[:3, :3] = A
    M[:3, 3:] = B * u
    m_exact = (expm(M * tf) @ np.append(m0, 1.0))[:3]
    P_exact = Phi @ P0 @ Phi.T
    # RK4 with h = 0.0125 s: global error ~1e-8
    np.testing.assert_allclose(m, m_exact[:2], rtol=1e-6, atol=3e-8)
    np.testing.assert_allclose(Pxx, P_exact[:2, :2], rtol=1e-6, atol=3e-8)
    np.testing.assert_allclose(Pxs, P_exact[:2, 2:], rtol=1e-6, atol=3e-8)


@pytest.mark.parametrize("second_order", [False, True])
def test_uncertain_decay_rate_against_lognormal(second_order):
    # x' = -s x, s ~ N(mu, sig^2): x(t) = x0 exp(-s t) is lognormal, so
    # E[x] = x0 exp(-mu t + sig^2 t^2 / 2); first-order CADET misses the exp factor,
    # the second-order term captures it up to O(sig^4 t^4).
    mu, sig, x0, tf = 1.0, 0.15, 2.0, 2.0
    sysm = CadetSystem(_decay(), nx=1, nu=1, ns=1, second_order=second_order)
    theta = CadetSystem.theta([mu], [[sig ** 2]])
    z0 = sysm.layout.pack([x0], [[0.0]], [[0.0]])
    Z, _ = sysm.propagate(z0=z0, controls=np.zeros((1, 41)), t_nodes=np.linspace(0, tf, 41),
                          theta=theta, substeps=5)
    m, Pxx, Pxs = sysm.layout.unpack(Z[:, -1])
    mean_exact = x0 * np.exp(-mu * tf + 0.5 * sig ** 2 * tf ** 2)
    var_exact = x0 ** 2 * (np.exp(-2 * mu * tf + 2 * sig ** 2 * tf ** 2) - np.exp(-2 * mu * tf + sig ** 2 * tf ** 2))
    # linearised variance misses the lognormal's higher-order growth (12.6% here)
    np.testing.assert_allclose(Pxx[0, 0], var_exact, rtol=0.15)
    if second_order:
        # to O(sig^4) the second-order equations give m = x0 e^{-mu t} (1 + sig^2 t^2 / 2)
        np.testing.assert_allclose(m[0], x0 * np.exp(-mu * tf) * (1 + 0.5 * sig ** 2 * tf ** 2), rtol=1e-3)
        assert abs(m[0] - mean_exact) < 0.01 * np.sqrt(var_exact)
    else:
        # first-order closed form: m = x0 e^{-mu t}, P_xs = -sig^2 x0 t e^{-mu t}, P_xx = sig^2 x0^2 t^2 e^{-2 mu t}
        np.testing.assert_allclose(m[0], x0 * np.exp(-mu * tf), rtol=1e-6)
        np.testing.assert_allclose(Pxs[0, 0], -sig ** 2 * x0 * tf * np.exp(-mu * tf), rtol=1e-6)
        np.testing.assert_allclose(Pxx[0, 0], sig ** 2 * x0 ** 2 * tf ** 2 * np.exp(-2 * mu * tf), rtol=1e-6)
        assert abs(m[0] - mean_exact) > 0.1 * np.sqrt(var_exact)


def test_output_moments_gradient_form():
    f, _, _ = _linear_oscillator()
    sysm = CadetSystem(f, nx=2, nu=1, ns=1)
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    s = ca.SX.sym("s", 1)
    c = ca.Function("c", [x, u, s], [ca.vertcat(x[0] ** 2 + 3 * s[0], x[1])])
    mom = sysm.output_moments(c)
    P = np.array([[0.04, 0.005, 0.02], [0.005, 0.01, 0.0], [0.02, 0.0, 0.25]])
    m = np.array([1.5, -0.2])
    z = sysm.layout.pack(m, P[:2, :2], P[:2, 2:])
    mu, var = mom(z, [0.0], CadetSystem.theta([0.1], [[0.25]]))
    g0 = np.array([2 * m[0], 0.0, 3.0])
    g1 = np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(np.asarray(mu).ravel(), [m[0] ** 2 + 0.3, m[1]], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(var).ravel(), [g0 @ P @ g0, g1 @ P @ g1], rtol=1e-12)


@pytest.mark.parametrize("second_order", [False, True])
def test_sensitivity_form_equals_covariance_form(second_order):
    # Nonlinear in the augmented state (stiffness times position), rank-1 initial covariance:
    # both forms solve the same moment equations.
    from solvers.uncertainty.cadet import CadetSensitivity

    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    s = ca.SX.sym("s", 2)
    f = ca.Function("f", [x, u, s], [ca.vertcat(x[1], -4.0 * (1 + s[0]) * x[0] - 0.3 * (1 + s[1]) * x[1] ** 3 + u[0])])
    P0 = np.outer([0.1, -0.05], [0.1, -0.05])
    theta = CadetSystem.theta([0.02, -0.1], np.diag([0.01, 0.04]))
    t = np.linspace(0, 3, 31)
    U = np.sin(t)[None, :]
    full = CadetSystem(f, nx=2, nu=1, ns=2, second_order=second_order)
    Zf, _ = full.propagate(z0=full.layout.pack([1.0, 0.0], P0, np.zeros((2, 2))), controls=U, t_nodes=t,
                           theta=theta, substeps=6)
    sens = CadetSensitivity(f, nx=2, nu=1, ns=2, r0=1, second_order=second_order)
    Zs, _ = sens.propagate(z0=sens.initial([1.0, 0.0], P0), controls=U, t_nodes=t, theta=theta, substeps=6)
    m1, Pxx1, Pxs1 = full.layout.unpack(Zf)
    m2, Pxx2, Pxs2 = sens.covariance(Zs, theta)
    assert sens.layout.nz == 8 and full.layout.nz == 9
    # RK4 of the two ODE systems agree to the integration error only
    np.testing.assert_allclose(m2, m1, rtol=0, atol=1e-7)
    np.testing.assert_allclose(Pxx2, Pxx1, rtol=0, atol=1e-7)
    np.testing.assert_allclose(Pxs2, Pxs1, rtol=0, atol=1e-7)
    assert np.max(Pxx1[0, 0]) > 1e-3
    # output moments agree too
    c = ca.Function("c", [x, u, s], [x[0] * x[1] + s[1]])
    mu1, v1 = full.output_moments(c).map(t.size)(Zf, U, theta)
    mu2, v2 = sens.output_moments(c).map(t.size)(Zs, U, theta)
    np.testing.assert_allclose(np.asarray(v2), np.asarray(v1), rtol=0, atol=1e-7)
    np.testing.assert_allclose(np.asarray(mu2), np.asarray(mu1), rtol=0, atol=1e-7)
