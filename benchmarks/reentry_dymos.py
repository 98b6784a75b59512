"""Dymos' own shuttle reentry example (Betts max crossrange), the baseline of ``benchmarks.reentry``.

Run by ``benchmarks.reentry`` in a fresh process: ``python -m benchmarks.reentry_dymos SEGMENTS``
prints one JSON line (setup and solve wall times, final latitude and time, peak RSS).

The problem is Dymos' ``dymos/examples/shuttle_reentry`` test problem (its ``ShuttleODE``, state
scaling and initial guess, unconstrained, Gauss-Lobatto order 3), as its test builds it, with one
change forced by what installs: its tests drive pyOptSparse (IPOPT or SNOPT), which is not on PyPI
as a wheel, so the optimizer is OpenMDAO's ``ScipyOptimizeDriver`` with SLSQP, Dymos' default
without pyOptSparse, with total-derivative coloring declared as in Dymos' examples.
"""
from __future__ import annotations

import json
import sys
import time

from benchmarks.memory import own_mb


def solve(segments: int = 30) -> dict:
    t0 = time.perf_counter()
    import dymos as dm
    import numpy as np
    import openmdao.api as om
    from dymos.examples.shuttle_reentry.shuttle_ode import ShuttleODE

    t_import = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    p = om.Problem(model=om.Group(), reports=False)
    p.driver = om.ScipyOptimizeDriver(optimizer="SLSQP", maxiter=300, tol=1e-6, disp=False)
    p.driver.declare_coloring()
    traj = p.model.add_subsystem("traj", dm.Trajectory())
    phase = traj.add_phase("phase0", dm.Phase(ode_class=ShuttleODE,
                                              transcription=dm.GaussLobatto(num_segments=segments, order=3)))
    phase.set_time_options(fix_initial=True, units="s", duration_ref=200)
    phase.add_state("h", fix_initial=True, fix_final=True, units="ft", rate_source="hdot", targets=["h"],
                    lower=0, ref0=75000, ref=300000, defect_ref=1000)
    phase.add_state("gamma", fix_initial=True, fix_final=True, units="rad", rate_source="gammadot",
                    targets=["gamma"], lower=-89. * np.pi / 180, upper=89. * np.pi / 180)
    phase.add_state("phi", fix_initial=True, fix_final=False, units="rad", rate_source="phidot",
                    lower=0, upper=89. * np.pi / 180)
    phase.add_state("psi", fix_initial=True, fix_final=False, units="rad", rate_source="psidot",
                    targets=["psi"], lower=0, upper=90. * np.pi / 180)
    phase.add_state("theta", fix_initial=True, fix_final=False, units="rad", rate_source="thetadot",
                    targets=["theta"], lower=-89. * np.pi / 180, upper=89. * np.pi / 180)
    phase.add_state("v", fix_initial=True, fix_final=True, units="ft/s", rate_source="vdot",
                    targets=["v"], lower=500, ref0=2500, ref=25000)
    phase.add_control("alpha", units="rad", opt=True, lower=-np.pi / 2, upper=np.pi / 2, targets=["alpha"])
    phase.add_control("beta", units="rad", opt=True, lower=-89 * np.pi / 180, upper=1 * np.pi / 180,
                      targets=["beta"])
    phase.add_objective("theta", loc="final", ref=-0.01)
    p.setup(check=False)
    phase.set_time_val(initial=0, duration=2000, units="s")
    phase.set_state_val("h", [260000, 80000], units="ft")
    phase.set_state_val("gamma", [-1 * np.pi / 180, -5 * np.pi / 180], units="rad")
    phase.set_state_val("phi", [0, 75 * np.pi / 180], units="rad")
    phase.set_state_val("psi", [90 * np.pi / 180, 10 * np.pi / 180], units="rad")
    phase.set_state_val("theta", [0, 25 * np.pi / 180], units="rad")
    phase.set_state_val("v", [25600, 2500], units="ft/s")
    phase.set_control_val("alpha", [17.4 * np.pi / 180, 17.4 * np.pi / 180], units="rad")
    phase.set_control_val("beta", [-75 * np.pi / 180, 0 * np.pi / 180], units="rad")
    t_setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    failed = p.run_driver()
    t_solve = time.perf_counter() - t0
    cpu = time.process_time() - c0
    ok = failed is False or getattr(failed, "success", None) is True
    return {"segments": segments, "iterations": int(getattr(p.driver, "iter_count", -1)), "import_s": t_import, "setup_s": t_setup, "solve_s": t_solve,
            "total_s": t_setup + t_solve, "cpu_s": cpu, "success": bool(ok),
            "lat_deg": float(p.get_val("traj.phase0.timeseries.theta", units="deg")[-1, 0]),
            "tf_s": float(p.get_val("traj.phase0.timeseries.time")[-1, 0]),
            "rss_mb": own_mb()}


if __name__ == "__main__":
    print(json.dumps(solve(int(sys.argv[1]) if len(sys.argv) > 1 else 30)))
