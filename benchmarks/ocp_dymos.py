"""Dymos on the ``ocp`` presets, a baseline of ``benchmarks.ocp`` (issue 24 item 7, peer (c)).

The preset as a Dymos 1.15.1 phase on the same number of intervals (``num_segments`` = the preset's
intervals, order 3): Gauss-Lobatto or Radau.  The right-hand side is the hand-written dynamics of
``benchmarks.ocp`` (the same the Opti forms use) inside an OpenMDAO component whose partials come
from CasADi, exact and sparse (one diagonal block per state and input, as Dymos' own examples
declare them); the states scaled (``ref``) by the preset's scales, its bounds, fixed boundary
values and straight-line guess; a Lagrange integrand as an extra state; the path limit of
bryson-denham as the state's upper bound, as the Opti forms pose it.

The optimizer is IPOPT (tol 1e-8, MUMPS) through cyipopt: pyOptSparse, Dymos' usual route to
IPOPT, has no wheel here, and SLSQP would be no fair baseline.  OpenMDAO's scipy driver sets the
problem up (design variables, constraints, scaling, total-derivative coloring); IPOPT replaces
SLSQP in it.  OpenMDAO gives no second derivatives, so IPOPT runs with its limited-memory
Hessian, as it does under pyOptSparse.  ``build`` is set-up to the first model run (coloring
included), ``ipopt`` the driver run.
"""
from __future__ import annotations

import os
import tempfile
import time

import casadi as ca
import numpy as np


def _ode_class(dyn, nx: int, nu: int, nq: int):
    import openmdao.api as om

    x, u = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    fx, fq = dyn(x, u)
    f = ca.vertcat(fx, fq) if nq else fx
    rhs = ca.Function("rhs", [x, u], [f])
    jac = ca.Function("rhs_jacobian", [x, u], [ca.jacobian(f, ca.vertcat(x, u))])

    class CasadiODE(om.ExplicitComponent):
        """The preset's right-hand side at every node; partials from CasADi (diagonal blocks)."""

        def initialize(self):
            self.options.declare("num_nodes", types=int)

        def setup(self):
            n = self.options["num_nodes"]
            ar = np.arange(n)
            for i in range(nx):
                self.add_input(f"x{i}", shape=(n,))
            for j in range(nu):
                self.add_input(f"u{j}", shape=(n,))
            for k in range(nx + nq):
                self.add_output(f"f{k}", shape=(n,))
                for i in range(nx):
                    self.declare_partials(f"f{k}", f"x{i}", rows=ar, cols=ar)
                for j in range(nu):
                    self.declare_partials(f"f{k}", f"u{j}", rows=ar, cols=ar)
            self._rhs = rhs.map(n)
            self._jac = jac.map(n)

        def _args(self, inputs):
            return (np.array([inputs[f"x{i}"] for i in range(nx)]), np.array([inputs[f"u{j}"] for j in range(nu)]))

        def compute(self, inputs, outputs):
            f_all = np.array(self._rhs(*self._args(inputs)))
            for k in range(nx + nq):
                outputs[f"f{k}"] = f_all[k]

        def compute_partials(self, inputs, partials):
            J = np.array(self._jac(*self._args(inputs)))       # (nx + nq) x ((nx + nu) * n)
            n = self.options["num_nodes"]
            J = J.reshape(nx + nq, n, nx + nu)
            for k in range(nx + nq):
                for i in range(nx):
                    partials[f"f{k}", f"x{i}"] = J[k, :, i]
                for j in range(nu):
                    partials[f"f{k}", f"u{j}"] = J[k, :, nx + j]

    return CasadiODE


def _ipopt_in_place_of_slsqp(box: dict):
    """A ``scipy.optimize.minimize`` look-alike that runs IPOPT (cyipopt) on what the driver hands it.

    ScipyOptimizeDriver caches the model run in ``fun`` (constraint values) and every derivative
    in ``jac`` (constraint Jacobians): SLSQP always calls fun, then jac, at each point, but IPOPT
    evaluates f, g and their derivatives in its own order, so every call first brings both caches
    to its x (without this IPOPT sees stale values: 1,600 iterations on the brachistochrone).
    """
    import cyipopt

    def minimize(fun, x0, args=(), method=None, jac=None, bounds=None, constraints=(), tol=None,
                 callback=None, options=None, **_):
        seen: dict = {"x": None, "jac": False}

        def at(x, need_jac):
            if seen["x"] is None or not np.array_equal(seen["x"], x):
                seen["f"] = float(np.asarray(fun(x)).ravel()[0])      # the driver's objective is a 1-vector
                seen["x"], seen["jac"] = x.copy(), False
            if need_jac and not seen["jac"]:
                seen["g"], seen["jac"] = np.asarray(jac(x)), True

        def objective(x):
            at(x, False)
            return seen["f"]

        def gradient(x):
            at(x, True)
            return seen["g"]

        def wrapped(con):
            def value(x):
                at(x, False)
                return con["fun"](x, *con.get("args", ()))

            def jacobian(x):
                at(x, True)
                return con["jac"](x, *con.get("args", ()))
            return {"type": con["type"], "fun": value, "jac": jacobian}

        res = cyipopt.minimize_ipopt(objective, x0, jac=gradient, bounds=bounds,
                                     constraints=[wrapped(c) for c in constraints],
                                     options={"tol": 1e-8, "print_level": 0, "sb": "yes", "max_iter": 3000,
                                              "hessian_approximation": "limited-memory"})
        res.success = res.status == 0
        box["res"] = res
        return res

    return minimize


def dymos_baseline(name: str, transcription: str, setup) -> dict | None:
    """The preset ``name`` in Dymos (``transcription`` "gl" or "radau"); ``setup`` is
    ``benchmarks.ocp._setup``.  None when Dymos or cyipopt is not installed."""
    try:
        import cyipopt  # noqa: F401
        import dymos as dm
        import openmdao.api as om
        import openmdao.drivers.scipy_optimizer as so
    except ImportError:
        return None
    # OpenMDAO writes a <problem>_out folder (coloring files) under its work dir: not in the checkout
    os.environ.setdefault("OPENMDAO_WORKDIR", tempfile.mkdtemp(prefix="trajlab-dymos-"))
    t_start = time.perf_counter()
    ph, grid, (dyn, mayer, sign), xs, us, (xl, xu, ul, uu), (tf_g, X_g, U_g) = setup(name)
    nx, nu = len(ph.states), len(ph.controls)
    nq = 0 if name != "bryson-denham" else 1
    tx = (dm.GaussLobatto if transcription == "gl" else dm.Radau)(num_segments=grid.intervals, order=3)
    phase = dm.Phase(ode_class=_ode_class(dyn, nx, nu, nq), transcription=tx)
    upper = {ph.state_names.index(c.text): c.upper for c in ph.path}
    for i, st in enumerate(ph.states):
        hi = min(xu[i], upper.get(i, np.inf))
        phase.add_state(f"x{i}", rate_source=f"f{i}", targets=[f"x{i}"], ref=float(xs[i]),
                        fix_initial=st.initial is not None, fix_final=st.final is not None,
                        lower=xl[i] if np.isfinite(xl[i]) else None, upper=hi if np.isfinite(hi) else None)
    if nq:
        phase.add_state("q", rate_source=f"f{nx}", fix_initial=True)
    for j in range(nu):
        phase.add_control(f"u{j}", targets=[f"u{j}"], ref=float(us[j]), continuity=True, rate_continuity=False,
                          lower=ul[j] if np.isfinite(ul[j]) else None, upper=uu[j] if np.isfinite(uu[j]) else None)
    fixed_tf = ph.time.final is not None
    if fixed_tf:
        phase.set_time_options(fix_initial=True, fix_duration=True)
    else:
        phase.set_time_options(fix_initial=True, duration_bounds=(ph.time.final_lower, ph.time.final_upper))
    # the objective: tf, the integral, or one state's final value (what the presets' Mayer terms are)
    X, T = ca.SX.sym("X", nx), ca.SX.sym("T")
    grad = np.array(ca.Function("g", [X, T], [ca.gradient(ca.SX(mayer(X, T)), ca.vertcat(X, T))])(X_g[:, -1], tf_g)).ravel()
    if nq:
        phase.add_objective("q", loc="final")
    elif grad[-1] != 0:
        phase.add_objective("time", loc="final", scaler=float(sign * grad[-1]))
    else:
        k = int(np.flatnonzero(grad[:-1])[0])
        phase.add_objective(f"x{k}", loc="final", scaler=float(sign * grad[k]))
    traj = dm.Trajectory()
    traj.add_phase("phase0", phase)
    p = om.Problem(reports=False)
    p.model.add_subsystem("traj", traj)
    p.driver = om.ScipyOptimizeDriver(optimizer="SLSQP")
    p.driver.declare_coloring()
    p.setup()
    phase.set_time_val(initial=ph.time.initial, duration=ph.time.final if fixed_tf else tf_g)
    for i, st in enumerate(ph.states):
        first = st.initial if st.initial is not None else X_g[i, 0]
        last = st.final if st.final is not None else X_g[i, -1]
        phase.set_state_val(f"x{i}", [first, last])
    if nq:
        phase.set_state_val("q", [0.0, 1.0])
    for j in range(nu):
        phase.set_control_val(f"u{j}", [U_g[j, 0], U_g[j, -1]])
    p.final_setup()
    box: dict = {}
    original = so.minimize
    so.minimize = _ipopt_in_place_of_slsqp(box)
    try:
        t_run = time.perf_counter()
        p.run_driver()
        ipopt_s = time.perf_counter() - t_run
    finally:
        so.minimize = original
    res = box.get("res")
    xf = np.array([p.get_val(f"traj.phase0.timeseries.x{i}")[-1, 0] for i in range(nx)])
    tf = float(p.get_val("traj.phase0.timeseries.time")[-1, 0])
    objective = float(p.get_val("traj.phase0.timeseries.q")[-1, 0]) if nq else float(mayer(xf, tf))
    total = time.perf_counter() - t_start
    return {"total_s": total, "build_s": total - ipopt_s, "ipopt_s": ipopt_s,
            "iterations": int(res.get("nit", -1)) if res is not None else -1, "objective": objective,
            "status": "Solve_Succeeded" if res is not None and res.status == 0 else
            (str(res.message)[:40] if res is not None else "no IPOPT run")}
