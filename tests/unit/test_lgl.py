"""LGL nodes, weights and differentiation matrix: exactness on polynomials."""
import numpy as np
import pytest
from numpy.polynomial import legendre as npleg

from solvers.transcription.lgl import (
    Mesh, collocation_constraints, lagrange_matrix, lgl_diff_matrix, lgl_integration_matrix, lgl_nodes,
    lgl_weights,
)


@pytest.mark.parametrize("n", [3, 4, 8, 15, 60, 120])
def test_nodes_are_endpoints_and_roots_of_legendre_derivative(n):
    x = lgl_nodes(n)
    assert x[0] == -1.0 and x[-1] == 1.0
    assert np.all(np.diff(x) > 0)
    dP = npleg.legder(np.eye(n)[n - 1])          # P'_{n-1}
    np.testing.assert_allclose(npleg.legval(x[1:-1], dP), 0.0, atol=1e-9 * n**2)
    np.testing.assert_allclose(x, -x[::-1], atol=1e-15)


@pytest.mark.parametrize("n", [3, 5, 10, 60])
def test_weights_integrate_degree_2n_minus_3_exactly(n):
    x, w = lgl_nodes(n), lgl_weights(n)
    for deg in range(0, 2 * n - 2):
        exact = 0.0 if deg % 2 else 2.0 / (deg + 1)
        assert abs(w @ x**deg - exact) < 1e-13, deg
    if n <= 10:   # and not degree 2n-2 (Lobatto, not Gauss); the gap vanishes for large n
        deg = 2 * n - 2
        assert abs(w @ x**deg - 2.0 / (deg + 1)) > 1e-6


@pytest.mark.parametrize("n", [3, 6, 12, 60])
def test_diff_matrix_differentiates_degree_n_minus_1_exactly(n):
    x, D = lgl_nodes(n), lgl_diff_matrix(n)
    rng = np.random.default_rng(n)
    c = rng.normal(size=n)                         # a random polynomial of degree n-1
    p = npleg.legval(x, c)
    dp = npleg.legval(x, npleg.legder(c))
    np.testing.assert_allclose(D @ p, dp, atol=1e-10 * n**2 * np.abs(c).sum())
    np.testing.assert_allclose(D.sum(axis=1), 0.0, atol=1e-10 * n**2)


@pytest.mark.parametrize("n", [4, 10, 30])
def test_summation_by_parts_identity(n):
    # W D + (W D)^T = diag(-1, 0, ..., 0, 1): the identity behind the costate mapping
    w, D = lgl_weights(n), lgl_diff_matrix(n)
    B = np.zeros((n, n))
    B[0, 0], B[-1, -1] = -1.0, 1.0
    np.testing.assert_allclose(w[:, None] * D + (w[:, None] * D).T, B, atol=1e-10 * n)


def test_lagrange_matrix_reproduces_polynomials_and_nodes():
    n = 9
    x = lgl_nodes(n)
    pts = np.linspace(-1, 1, 37)
    c = np.arange(1.0, n + 1)
    L = lagrange_matrix(x, pts)
    np.testing.assert_allclose(L @ npleg.legval(x, c), npleg.legval(pts, c), atol=1e-11)
    np.testing.assert_allclose(lagrange_matrix(x, x), np.eye(n), atol=0)


def test_mesh_interpolation():
    mesh = Mesh.uniform(4, 6)
    s = mesh.node_fractions()
    vals = np.sin(3 * s)[None]
    fine = np.linspace(0, 1, 101)
    np.testing.assert_allclose(mesh.interpolate(vals, fine)[0], np.sin(3 * fine), atol=1e-5)
    with pytest.raises(ValueError):
        Mesh((0.0, 0.6, 0.5, 1.0), 5)


@pytest.mark.parametrize("n", [3, 6, 10, 30])
def test_integration_matrix_integrates_degree_n_minus_1_exactly(n):
    x, A = lgl_nodes(n), lgl_integration_matrix(n)
    rng = np.random.default_rng(n)
    c = rng.normal(size=n)
    antider = npleg.legint(c, lbnd=-1.0)
    np.testing.assert_allclose(A @ npleg.legval(x, c), npleg.legval(x, antider), atol=1e-12 * np.abs(c).sum())
    np.testing.assert_allclose(A[-1], lgl_weights(n), atol=1e-14)
    assert not A[0].any()


def test_integral_form_solves_a_control_free_ode_where_the_differential_form_cannot():
    """x' = -x on one segment from x(-1) = 1: the integral form has a solution (exact to the
    quadrature's order); the differential form's n equations on n-1 free states do not."""
    import casadi as ca
    from scipy.optimize import least_squares
    n = 8
    x_sym, u_sym, p_sym = ca.SX.sym("x"), ca.SX.sym("u", 0), ca.SX.sym("p", 0)
    f = ca.Function("f", [x_sym, u_sym, p_sym], [-x_sym])
    Xf = ca.SX.sym("X", 1, n - 1)
    X = ca.horzcat(ca.DM(1.0), Xf)
    res = {}
    for form in ("integral", "differential"):
        d, _ = collocation_constraints(dynamics=f, X=X, U=ca.SX(0, n), params=ca.SX(0, 1),
                                       seg_duration=ca.DM(2.0), nodes=n, segments=1, form=form)
        F = ca.Function("F", [Xf], [ca.vec(d)])
        J = ca.Function("J", [Xf], [ca.jacobian(ca.vec(d), Xf)])
        sol = least_squares(lambda z, F=F: np.asarray(F(z)).ravel(), np.ones(n - 1),
                            jac=lambda z, J=J: np.asarray(J(z)), xtol=1e-15, ftol=1e-15, gtol=1e-15)
        res[form] = (np.max(np.abs(sol.fun)), sol.x)
    assert res["integral"][0] < 1e-13
    np.testing.assert_allclose(res["integral"][1], np.exp(-(lgl_nodes(n)[1:] + 1.0)), rtol=1e-7)
    assert res["differential"][0] > 1e-7        # overdetermined: no exact solution
