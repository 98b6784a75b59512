"""Per-interval block derivatives (solvers.transcription.blocks) equal CasADi's AD of the whole NLP."""
import dataclasses

import casadi as ca
import numpy as np
import pytest

from solvers.transcription import jit
from solvers.transcription.multiple_shooting import (
    PathConstraint,
    ShootingProblem,
    Transcription,
)


def toy(control: str) -> ShootingProblem:
    """Every block kind: Lagrange and Mayer terms, node, substep and integral path constraints,
    terminal constraints, a free final time and parameters."""
    return ShootingProblem(
        key=("blocks-toy", control), nx=3, nu=2, n_params=2,
        dynamics=lambda x, u, p: ca.vertcat(x[1], u[0] - p[0] * x[1] ** 2 + ca.sin(x[2]), x[0] * u[1]),
        x_scale=(2.0, 0.5, 1.0), u_scale=(1.0, 3.0), t_scale=10.0, intervals=5, control=control,
        substeps=3, mayer=lambda xf, T, p: -xf[0] * xf[2] + 0.1 * T ** 2,
        lagrange=lambda x, u, p: u[0] ** 2 + x[1] * u[1], objective_scale=2.0,
        path=(PathConstraint("a", lambda x, u, p: ca.vertcat(x[0] ** 2 - p[1], x[1] * u[0]), size=2,
                             where="substeps"),
              PathConstraint("b", lambda x, u, p: ca.exp(x[2]) - 2, where="nodes"),
              PathConstraint("c", lambda x, u, p: x[1] * x[2] - 1, integral=True)),
        terminal=lambda xf, p: ca.vertcat(xf[1] ** 2, xf[0] * xf[2]), n_terminal=2)


@pytest.mark.parametrize("control", ["linear", "constant"])
def test_block_hessian_and_jacobian_equal_casadi_ad(control):
    prob = toy(control)
    ours = Transcription(dataclasses.replace(prob, block_derivatives=True)).solver.solver
    ref = Transcription(prob).solver.solver
    rng = np.random.default_rng(1)
    n, ng = ref.size1_in("x0"), ref.size1_in("lam_g0")
    x, p, lam_g = rng.uniform(0.2, 1.0, n), rng.uniform(0.2, 1.0, 2), rng.standard_normal(ng)
    for name, args in (("nlp_jac_g", (x, p)), ("nlp_hess_l", (x, p, 0.7, lam_g))):
        a, b = ours.get_function(name)(*args), ref.get_function(name)(*args)
        a, b = (a[-1], b[-1]) if isinstance(a, tuple) else (a, b)
        np.testing.assert_allclose(np.array(ca.DM(a)), np.array(ca.DM(b)), rtol=1e-12, atol=1e-12)
        if name == "nlp_hess_l":
            assert ca.DM(a).sparsity().is_triu()


def _solve(tr: Transcription):
    m = tr.prob.intervals
    nx, nu = tr.prob.nx, tr.prob.nu
    return tr.solve(p=[0.3, 4.0], x_lb=np.full((nx, m + 1), -5.0), x_ub=np.full((nx, m + 1), 5.0),
                    u_lb=[-1.0, -1.0], u_ub=[1.0, 1.0], tf_bounds=(5.0, 20.0),
                    guess=(10.0, np.full((nx, m + 1), 0.5), np.zeros((nu, tr.nu_nodes))),
                    terminal_bounds=([-np.inf] * 2, [1.0] * 2))


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_compiled_blocks_give_the_vm_answer_and_are_shared(tmp_path, monkeypatch):
    monkeypatch.setenv("TRAJLAB_JIT_CACHE", str(tmp_path))
    monkeypatch.setenv("TRAJLAB_JIT", "off")
    prob = dataclasses.replace(toy("linear"), block_derivatives=True, ipopt={"tol": 1e-9})
    vm = _solve(Transcription(dataclasses.replace(prob, key=("blocks-toy-vm",))))
    assert vm.status.ok and not vm.status.details["compiled_derivatives"]
    monkeypatch.setenv("TRAJLAB_JIT", "sync")
    prob = dataclasses.replace(prob, key=("blocks-toy-jit",))
    a = Transcription(prob)
    # A second structure with the same blocks (other IPOPT options: the robust stages) loads
    # the first one's library instead of compiling again.
    b = Transcription(dataclasses.replace(prob, ipopt={"tol": 1e-10}))
    assert a.solver.compiled and b.solver.compiled and len(list(tmp_path.glob("nlp_*.so"))) == 1
    res = _solve(a)
    assert res.status.ok and res.status.details["compiled_derivatives"]
    assert res.status.iterations == vm.status.iterations
    np.testing.assert_allclose(res.x, vm.x, rtol=0, atol=1e-9)


@pytest.mark.skipif(jit.compiler() is None, reason="no C compiler on PATH")
def test_background_compile_swaps_in_every_solver_sharing_the_blocks(tmp_path, monkeypatch):
    import time
    monkeypatch.setenv("TRAJLAB_JIT_CACHE", str(tmp_path))
    monkeypatch.setenv("TRAJLAB_JIT", "background")
    prob = dataclasses.replace(toy("constant"), block_derivatives=True, key=("blocks-toy-bg",))
    with jit.expected_again():                  # worth compiling on first sight (jit's policy)
        a = Transcription(dataclasses.replace(prob, ipopt={"tol": 1e-9}))
        b = Transcription(dataclasses.replace(prob, ipopt={"tol": 1e-10}))
    assert _solve(a).status.ok                  # answered in the VM while gcc runs
    deadline = time.monotonic() + 120
    while not (a.solver.compiled and b.solver.compiled) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert a.solver.compiled and b.solver.compiled
    assert _solve(b).status.details["compiled_derivatives"]


def _reentry_cases():
    """Every path of the reentry kind the blocks serve: the objectives' Mayer and Lagrange terms,
    all path enforcements (integral too), both control modes, the vehicle models as data."""
    from solvers import reentry as rs
    from solvers.models import shuttle as sh
    from solvers.models.aerodynamics import sample_polynomials
    from solvers.models.atmosphere import Atmosphere
    from solvers.models.heating import SuttonGraves

    h = np.arange(0.0, 130001.0, 5000.0)
    table_vehicle = dataclasses.replace(
        sh.SHUTTLE, rotating_earth=True, heating=SuttonGraves(nose_radius_m=0.5),
        aero_table=sample_polynomials(cl_coeffs=sh.SHUTTLE.cl_coeffs, cd_coeffs=sh.SHUTTLE.cd_coeffs,
                                      alpha_deg=np.arange(-90.0, 90.1, 5.0), mach=(0.5, 5.0, 15.0, 40.0)),
        atmosphere=Atmosphere(kind="table", altitudes_m=h, densities_kg_m3=sh.BETTS_ATMOSPHERE.density(h)))
    limits = {"max_heat_rate_w_m2": 794955.0, "max_dynamic_pressure_pa": 1.5e4, "max_load_factor": 2.5}
    return [
        rs.ReentryProblem(intervals=8, **limits),
        rs.ReentryProblem(intervals=8, objective="min_heat_load", control="constant",
                          path_enforcement="integral", **limits),
        rs.ReentryProblem(intervals=8, objective="max_great_circle_range", path_enforcement="midpoints",
                          substeps=4, vehicle=table_vehicle, **limits),
        rs.ReentryProblem(intervals=8, objective="min_time", path_enforcement="nodes", **limits),
    ]


@pytest.mark.parametrize("case", range(4))
def test_reentry_structures_use_blocks_equal_to_casadi_ad(case):
    from solvers import reentry as rs
    from solvers.reentry.guess import on_grid, simulate_constant_controls

    problem = _reentry_cases()[case]
    sp = rs.shooting_problem(problem)
    assert sp.block_derivatives
    ours, ref = Transcription(sp), Transcription(dataclasses.replace(sp, block_derivatives=False))
    guess = simulate_constant_controls(problem, alpha_rad=0.3, bank_rad=-1.0)
    rng = np.random.default_rng(case)
    z = ref.pack(*on_grid(guess, problem.intervals, problem.control))
    z = z * (1.0 + 1e-3 * rng.standard_normal(z.size))
    p, lam_g = rs.param_vector(problem), rng.standard_normal(ref.ng)
    for name, args in (("nlp_jac_g", (z, p)), ("nlp_hess_l", (z, p, 0.7, lam_g))):
        a = ours.solver.solver.get_function(name)(*args)
        b = ref.solver.solver.get_function(name)(*args)
        a, b = (a[-1], b[-1]) if isinstance(a, tuple) else (a, b)
        a, b = np.array(ca.DM(a)), np.array(ca.DM(b))
        if name == "nlp_hess_l":
            a, b = np.triu(a), np.triu(b)       # IPOPT reads the upper triangle
        assert np.all(np.isfinite(b))
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * np.abs(b).max())


def test_the_least_peak_minmax_problem_uses_blocks_equal_to_casadi_ad():
    # The epigraph form (solvers.reentry.minmax) adds a constant state and a path constraint on it;
    # its blocks must still be the AD's derivatives (issue 35 item 8 solves it before every
    # heat-limited job).
    from solvers import reentry as rs
    from solvers.reentry.guess import on_grid, simulate_constant_controls
    from solvers.reentry.minmax import minmax_problem

    problem = rs.ReentryProblem(intervals=6, substeps=4, max_heat_rate_w_m2=5e5)
    mp = minmax_problem(rs.shooting_problem(problem))
    assert mp.block_derivatives and mp.nx == 7
    ours, ref = Transcription(mp), Transcription(dataclasses.replace(mp, block_derivatives=False))
    tf, x, u = on_grid(simulate_constant_controls(problem, alpha_rad=0.3, bank_rad=-1.0), 6, problem.control)
    rng = np.random.default_rng(7)
    z = ref.pack(tf, np.vstack([x, np.full((1, 7), 1.2)]), u)
    z = z * (1.0 + 1e-3 * rng.standard_normal(z.size))
    p, lam_g = rs.param_vector(problem), rng.standard_normal(ref.ng)
    for name, args in (("nlp_jac_g", (z, p)), ("nlp_hess_l", (z, p, 0.7, lam_g))):
        a = ours.solver.solver.get_function(name)(*args)
        b = ref.solver.solver.get_function(name)(*args)
        a, b = (a[-1], b[-1]) if isinstance(a, tuple) else (a, b)
        a, b = np.array(ca.DM(a)), np.array(ca.DM(b))
        if name == "nlp_hess_l":
            a, b = np.triu(a), np.triu(b)
        assert np.all(np.isfinite(b))
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * np.abs(b).max())
