"""Robust reentry benchmark: solve times and Monte Carlo throughput, each against a baseline of the same run.

    python -m benchmarks.robust [--samples 10000]

Rows: the deterministic (DO) solve is the baseline of the solve rows; the robust (RO) solve in
its two-stage continuation and direct form; per-sample ``solve_ivp`` (DOP853, one sample at a
time, the way a naive Monte Carlo runs) is the baseline of the vectorized Monte Carlo.
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from scipy.integrate import solve_ivp

from solvers import robust_reentry as rr
from solvers import robust_reentry_mc
from solvers.models import reentry_dynamics as dyn
from solvers.uncertainty import montecarlo as mc


def _solve(continuation: str):
    problem = rr.RobustReentryProblem(robust=rr.RobustSettings(continuation=continuation))
    problem.base.substeps = 2
    t0 = time.perf_counter()
    sol = rr.solve(problem)
    return problem, sol, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=10000)
    ap.add_argument("--ivp-samples", type=int, default=5)
    args = ap.parse_args()

    rows = []
    problem, sol, wall2 = _solve("two_stage")
    do = sol.deterministic
    do_time = do.status.solve_time_s + do.status.build_time_s
    rows.append(("DO solve (heat-limited Betts, 2 stages)", do_time, do.status.iterations, do_time, do.status.solver_status))
    ro_stages = [s for s in sol.stages if s["stage"].startswith("robust")]
    ro_time = sum(s["solve_time_s"] for s in ro_stages) + sol.status.build_time_s
    rows.append(("RO solve, two-stage continuation", ro_time, sum(s["iterations"] for s in ro_stages), do_time,
                 sol.status.solver_status))
    _, sol_d, _ = _solve("direct")
    rd = [s for s in sol_d.stages if s["stage"].startswith("robust")]
    rows.append(("RO solve, direct (same optimum)", sum(s["solve_time_s"] for s in rd) + sol_d.status.build_time_s,
                 sum(s["iterations"] for s in rd), do_time, sol_d.status.solver_status))

    pred = rr.predict(problem, t=sol.t, u=sol.u, second_order=True)
    spec = rr.monte_carlo_spec(problem, t=sol.t, u=sol.u, cadet_sigma=pred.terminal_sigma, substeps=5)
    model = mc.resolve_model(spec["model"], spec["model_params"])
    x0, s = mc.draw_samples(spec, 1, 0, args.ivp_samples, nx=6, ns=2)
    t, U = np.asarray(spec["t_nodes"]), np.asarray(spec["controls"])
    v = problem.base.vehicle
    t0 = time.perf_counter()
    for i in range(args.ivp_samples):
        ui = lambda tt: np.array([np.interp(tt, t, U[0]), np.interp(tt, t, U[1])])  # noqa: E731
        solve_ivp(lambda tt, y: dyn.eom(y, ui(tt), v, np, cd_scale=1 + s[0, i], cl_scale=1 + s[1, i]),
                  (t[0], t[-1]), x0[:, i], method="DOP853", rtol=1e-8, atol=1e-8)
    ivp_rate = args.ivp_samples / (time.perf_counter() - t0)
    t0 = time.perf_counter()
    mc.run_monte_carlo(spec, args.samples, 2020, chunk_size=2500)
    mc_time = time.perf_counter() - t0
    mc_rate = args.samples / mc_time
    # The same run without the plots' envelope, sample traces and terminal samples: their cost.
    mc.register_model("shuttle_reentry_untraced", lambda p: dataclasses.replace(
        robust_reentry_mc.monte_carlo_model(p), trace=None, sampled_terminal=()))
    t0 = time.perf_counter()
    mc.run_monte_carlo({**spec, "model": "shuttle_reentry_untraced"}, args.samples, 2020, chunk_size=2500)
    bare_time = time.perf_counter() - t0

    print(f"robust reentry benchmark (paper 001), {problem.base.intervals} intervals; timings on a shared, "
          f"loaded 2-core machine")
    print(f"{'case':44s} {'time_s':>8s} {'iters':>6s} {'x DO':>7s}  status")
    for name, tm, it, base, st in rows:
        print(f"{name:44s} {tm:8.2f} {it:6d} {tm / base:7.2f}  {st}")
    print()
    print(f"{'Monte Carlo':44s} {'samples/s':>10s} {'x solve_ivp':>12s}")
    print(f"{'solve_ivp DOP853 per sample (baseline)':44s} {ivp_rate:10.1f} {1.0:12.1f}")
    print(f"{'vectorized RK4, 5 steps/interval':44s} {mc_rate:10.1f} {mc_rate / ivp_rate:12.1f}"
          f"   ({args.samples} samples in {mc_time:.2f} s)")
    print(f"{'  the same without plot data (envelope, traces)':44s} {args.samples / bare_time:10.1f} "
          f"{args.samples / bare_time / ivp_rate:12.1f}   (plot data cost {100 * (mc_time / bare_time - 1):+.1f}%)")
    print()
    print(f"tf DO {do.tf_s:.2f} s, RO {sol.tf_s:.2f} s; RO direct tf {sol_d.tf_s:.2f} s")


if __name__ == "__main__":
    main()
