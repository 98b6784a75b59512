"""Two-body propagation against an independent integrator and known invariants."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from solvers.astro.kepler import propagate, stumpff

MU = 398600.4418e9


def _two_body_rhs(_t, y):
    r = y[:3]
    return np.concatenate([y[3:], -MU * r / np.linalg.norm(r) ** 3])


@pytest.mark.parametrize(
    "r0,v0,dt",
    [
        ([7000e3, 0.0, 0.0], [0.0, 7.5e3, 1.0e3], 5000.0),         # ellipse
        ([7000e3, 1000e3, 0.0], [-1.0e3, 11.5e3, 2.0e3], 8000.0),  # hyperbola
        ([6678e3, 0.0, 0.0], [0.0, 0.0, 7725.8], -3000.0),         # backwards in time
    ],
)
def test_propagate_matches_numerical_integration(r0, v0, dt):
    r, v = propagate(MU, r0, v0, dt)
    sol = solve_ivp(_two_body_rhs, (0.0, dt), np.r_[r0, v0], method="DOP853", rtol=1e-12, atol=1e-6)
    assert sol.success
    np.testing.assert_allclose(r, sol.y[:3, -1], rtol=0, atol=1e-3 * 1e3)  # 1 m
    np.testing.assert_allclose(v, sol.y[3:, -1], rtol=0, atol=1e-3)        # 1 mm/s


def test_vectorized_over_times_and_period_wrap():
    r0 = np.array([7000e3, 0.0, 0.0])
    v0 = np.array([0.0, 7.2e3, 1.5e3])
    a = 1.0 / (2.0 / 7000e3 - (v0 @ v0) / MU)
    period = 2 * np.pi * np.sqrt(a ** 3 / MU)
    dts = np.array([0.0, 0.5 * period, period, 10.5 * period])
    r, v = propagate(MU, r0, v0, dts)
    assert r.shape == (4, 3) and v.shape == (4, 3)
    np.testing.assert_allclose(r[0], r0, atol=1e-6)
    np.testing.assert_allclose(r[2], r0, atol=1e-3)
    np.testing.assert_allclose(r[3], r[1], atol=1e-2)
    # energy and angular momentum are conserved to rounding
    energy = 0.5 * np.einsum("ij,ij->i", v, v) - MU / np.linalg.norm(r, axis=1)
    np.testing.assert_allclose(energy, energy[0], rtol=1e-11)
    h = np.cross(r, v)
    h0 = np.cross(r0, v0)
    np.testing.assert_allclose(h, np.broadcast_to(h0, h.shape), rtol=0, atol=1e-11 * np.linalg.norm(h0))


def test_stumpff_series_matches_closed_form_at_the_switch():
    z = np.array([-0.1000001, -0.0999999, 0.0999999, 0.1000001, 0.0])
    c, s = stumpff(z)
    np.testing.assert_allclose(c[:2], c[1::-1], rtol=1e-5)
    np.testing.assert_allclose(c[4], 0.5, rtol=1e-15)
    np.testing.assert_allclose(s[4], 1 / 6, rtol=1e-15)
    sz = np.sqrt(0.1000001)
    np.testing.assert_allclose(c[2], (1 - np.cos(sz)) / 0.1000001, rtol=1e-6)
    np.testing.assert_allclose(s[2], (sz - np.sin(sz)) / sz ** 3, rtol=1e-6)


from hypothesis import given, settings, strategies as st  # noqa: E402

from solvers.astro.elements import Elements, elements_to_state  # noqa: E402


@settings(max_examples=25, deadline=None)
@given(
    rp=st.floats(6600e3, 40000e3), e=st.floats(0.0, 3.0), inc=st.floats(0.0, np.pi),
    nu=st.floats(-1.5, 1.5), dt=st.floats(-20000.0, 20000.0),
)
def test_property_matches_integration_for_ellipses_and_hyperbolas(rp, e, inc, nu, dt):
    a = rp / (1.0 - e) if abs(1.0 - e) > 1e-3 else None
    if a is None:
        return  # the near-parabolic element set is ill-conditioned, not the propagator
    r0, v0 = elements_to_state(MU, Elements(a=a, e=e, i=inc, raan=0.4, argp=1.1, nu=nu))
    r, v = propagate(MU, r0, v0, dt)
    sol = solve_ivp(_two_body_rhs, (0.0, dt), np.r_[r0, v0], method="DOP853", rtol=1e-12, atol=1e-6)
    scale = max(np.linalg.norm(r), np.linalg.norm(r0))
    assert np.linalg.norm(r - sol.y[:3, -1]) < 1e-8 * scale + 1e-3
    assert np.linalg.norm(v - sol.y[3:, -1]) < 1e-8 * np.linalg.norm(v) + 1e-6
