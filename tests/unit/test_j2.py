"""Launch-inertial frame, J2 acceleration and heyoka propagation (paper 002 eqs. (1)-(5))."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from solvers.astro.j2 import (
    GravityConstants,
    J2Propagator,
    LaunchFrame,
    j2_acceleration,
    j2_rhs,
)

C = GravityConstants()
# Spec midcourse.md: the frame fitted to paper 002's nominal.
PAPER_FRAME = LaunchFrame.from_geodetic(latitude_rad=np.radians(28.3214),
                                        azimuth_rad=np.radians(135.7033), height_m=1757.5)
R0_SPEC = np.array([12772.4, 6375087.7, 12462.7])
R_INIT = np.array([4052278.09, -1153200.39, -103191.17])
V_INIT = np.array([8297.4213, -5571.1055, 398.5626])
R_TGT = np.array([-14219839.24, -35409571.30, 667441.50])
V_TGT = np.array([-1889.2754, 781.3548, -73.1586])


def potential(r, w):
    rn = np.linalg.norm(r, axis=-1)
    s = (r @ w) / rn
    return C.mu / rn * (1.0 - 0.5 * C.j2 * (C.ae / rn) ** 2 * (3.0 * s**2 - 1.0))


def test_launch_frame_reproduces_spec_r0_and_eq4_spin_axis():
    assert np.allclose(PAPER_FRAME.r0, R0_SPEC, atol=0.5)           # spec gives R0 to 0.1 m
    b, a = np.radians(28.3214), np.radians(135.7033)
    w_eq4 = np.array([np.cos(b) * np.cos(a), np.sin(b), -np.cos(b) * np.sin(a)])
    assert np.allclose(PAPER_FRAME.spin_axis, w_eq4, atol=1e-14)


def test_eci_frame_is_identity():
    f = LaunchFrame.eci()
    assert np.array_equal(f.r0, np.zeros(3)) and np.array_equal(f.spin_axis, [0.0, 0.0, 1.0])


def test_acceleration_is_gradient_of_j2_potential():
    rng = np.random.default_rng(3)
    w = PAPER_FRAME.spin_axis
    r = rng.normal(size=(20, 3))
    r *= (rng.uniform(6.6e6, 4e7, 20) / np.linalg.norm(r, axis=1))[:, None]
    acc = j2_acceleration(r, w)
    h = 1.0
    grad = np.stack([(potential(r + h * e, w) - potential(r - h * e, w)) / (2 * h) for e in np.eye(3)], axis=1)
    assert np.allclose(acc, grad, rtol=1e-7, atol=1e-9)


def test_nominal_lands_on_the_paper_target():
    # Spec: with the fitted frame the error-free nominal lands within about 2 m and 0.02 m/s.
    prop = J2Propagator(PAPER_FRAME.spin_axis)
    end = prop.propagate(np.r_[R_INIT + PAPER_FRAME.r0, V_INIT][None], t0=0.0, t1=12900.0)[0]
    assert np.linalg.norm(end[:3] - PAPER_FRAME.r0 - R_TGT) < 3.0
    assert np.linalg.norm(end[3:] - V_TGT) < 0.02


def test_heyoka_matches_scipy_dop853():
    w = PAPER_FRAME.spin_axis
    y0 = np.r_[R_INIT + PAPER_FRAME.r0, V_INIT + np.array([10.0, -10.0, 10.0])]
    ref = solve_ivp(j2_rhs, (0.0, 12900.0), y0, method="DOP853", rtol=1e-12, atol=1e-6, args=(w, C)).y[:, -1]
    got = J2Propagator(w).propagate(y0[None], t0=0.0, t1=12900.0)[0]
    assert np.linalg.norm(got[:3] - ref[:3]) < 0.05      # m, over 12900 s
    assert np.linalg.norm(got[3:] - ref[3:]) < 1e-5      # m/s


def test_batch_propagation_equals_dense_output_for_any_count_and_interval():
    w = PAPER_FRAME.spin_axis
    prop = J2Propagator(w)
    y0 = np.r_[R_INIT + PAPER_FRAME.r0, V_INIT]
    dense = prop.dense(y0, t0=0.0, t1=12900.0)
    t_start = np.array([0.0, 100.0, 2500.0, 4000.0, 4000.0, 6000.0, 7000.0, 8000.0, 9000.0, 12000.0, 3.0])
    t_end = np.array([12900.0, 5000.0, 2500.0, 12000.0, 4100.0, 6500.0, 12900.0, 8000.5, 12800.0, 12900.0, 7.0])
    out = prop.propagate(dense(t_start), t0=t_start, t1=t_end)   # 11 rows: not a multiple of the SIMD width
    expect = dense(t_end)
    assert np.allclose(out[:, :3], expect[:, :3], rtol=0, atol=1e-3)
    assert np.allclose(out[:, 3:], expect[:, 3:], rtol=0, atol=1e-6)


def test_energy_and_axial_angular_momentum_are_conserved():
    # J2 is axisymmetric about the spin axis: E and h.w are first integrals.
    w = PAPER_FRAME.spin_axis
    y0 = np.r_[R_INIT + PAPER_FRAME.r0, V_INIT]
    states = J2Propagator(w).dense(y0, t0=0.0, t1=12900.0)(np.linspace(0.0, 12900.0, 50))
    energy = 0.5 * np.sum(states[:, 3:] ** 2, axis=1) - potential(states[:, :3], w)
    hz = np.cross(states[:, :3], states[:, 3:]) @ w
    assert np.ptp(energy) / abs(energy[0]) < 1e-11
    assert np.ptp(hz) / abs(hz[0]) < 1e-11


def test_acceleration_on_the_equator_is_radial_and_stronger_than_point_mass():
    # On the equator (r perpendicular to the spin axis) sin(phi)=0: g is purely radial.
    acc = j2_acceleration(np.array([7e6, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    expect = -C.mu / 7e6**2 * (1.0 + 1.5 * C.j2 * (C.ae / 7e6) ** 2)
    assert acc[2] == 0.0 and acc[1] == 0.0
    assert acc[0] == pytest.approx(expect, rel=1e-14)
