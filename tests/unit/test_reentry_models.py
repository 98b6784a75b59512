"""Reentry physics: units, numpy/CasADi agreement, vectorization, exact derivatives."""
import casadi as ca
import numpy as np
import pytest

from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.models.atmosphere import Atmosphere

X0 = np.array(sh.BETTS_INITIAL_STATE)
U0 = np.array([17.0 * sh.DEG, -60.0 * sh.DEG])


def test_heat_rate_matches_betts_fit_in_english_units():
    # Betts eq. 6.101 evaluated by hand in English units at the entry state, alpha 17 deg.
    a = 17.0
    rho = 0.002378 * np.exp(-260000.0 / 23800.0)
    q_btu = ((1.0672181 - 0.19213774e-1 * a + 0.21286289e-3 * a**2 - 0.10117249e-5 * a**3)
             * 17700 * np.sqrt(rho) * (0.0001 * 25600.0) ** 3.07)
    assert dyn.heat_rate(X0, U0, sh.SHUTTLE) == pytest.approx(q_btu * 11356.5, rel=1e-12)
    assert sh.BETTS_HEAT_LIMIT_W_M2 == pytest.approx(794955.0, abs=1e-6)


def test_eom_in_si_equals_betts_english_units():
    # Same state in ft and slug: dv/dt converted must agree (unit conversions consistent).
    h, v, gam = 260000.0, 25600.0, -1.0 * sh.DEG
    rho = 0.002378 * np.exp(-h / 23800.0)
    cd = 0.07854 - 0.61592e-2 * 17 + 0.621408e-3 * 17**2
    m = 203000.0 / 32.174
    r = 20902900.0 + h
    dv_fps2 = -0.5 * rho * v**2 * 2690.0 * cd / m - 0.14076539e17 / r**2 * np.sin(gam)
    assert dyn.eom(X0, U0, sh.SHUTTLE)[3] == pytest.approx(dv_fps2 * 0.3048, rel=1e-9)


def test_vectorized_and_symbolic_agree():
    n = 5
    X = X0[:, None] * np.linspace(0.9, 1.0, n)[None, :]
    U = np.tile(U0[:, None], (1, n))
    scale = np.linspace(0.98, 1.02, n)
    vec = dyn.eom(X, U, sh.SHUTTLE, cd_scale=scale)
    xs, us, s = ca.SX.sym("x", 6), ca.SX.sym("u", 2), ca.SX.sym("s")
    f = ca.Function("f", [xs, us, s], [dyn.eom(xs, us, sh.SHUTTLE, ca, cd_scale=s)])
    for j in range(n):
        assert np.allclose(vec[:, j], np.asarray(f(X[:, j], U[:, j], scale[j])).ravel(), rtol=1e-13)


def test_exact_derivatives_match_finite_differences():
    import dataclasses
    veh = dataclasses.replace(sh.SHUTTLE, rotating_earth=True)
    xs, us = ca.SX.sym("x", 6), ca.SX.sym("u", 2)
    rhs = ca.vertcat(dyn.eom(xs, us, veh, ca), dyn.heat_rate(xs, us, veh, ca))
    jac = ca.Function("j", [xs, us], [ca.jacobian(rhs, ca.vertcat(xs, us))])
    f = ca.Function("f", [xs, us], [rhs])
    x = X0 + np.array([-20000.0, 0.3, 0.2, -1000.0, -0.02, -0.3])
    J = np.asarray(jac(x, U0))
    w = np.concatenate([x, U0])
    step = np.array([1.0, 1e-6, 1e-6, 1e-3, 1e-7, 1e-6, 1e-7, 1e-7])
    for k in range(8):
        e = np.zeros(8)
        e[k] = step[k]
        fp = np.asarray(f((w + e)[:6], (w + e)[6:])).ravel()
        fm = np.asarray(f((w - e)[:6], (w - e)[6:])).ravel()
        fd = (fp - fm) / (2 * step[k])
        assert np.allclose(J[:, k], fd, rtol=1e-5, atol=1e-9 * np.abs(J).max(axis=1)), k


def test_us1976_density_anchor_values():
    a = Atmosphere("us1976")
    # U.S. Standard Atmosphere 1976 table values (kg/m^3).
    assert a.density(0.0) == pytest.approx(1.2250, rel=1e-4)
    assert a.density(11000.0) == pytest.approx(0.36480, rel=2e-3)
    assert a.density(50000.0) == pytest.approx(1.0269e-3, rel=2e-3)
    assert a.density(80000.0) == pytest.approx(1.846e-5, rel=1e-2)
