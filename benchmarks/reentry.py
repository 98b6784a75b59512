"""Betts shuttle reentry: CasADi/IPOPT multiple shooting vs a scipy SLSQP baseline, same run.

Run ``python -m benchmarks.reentry``.  For each Betts preset and grid (50/100/200 intervals) it
prints final latitude, tf, IPOPT iterations, build time (cold, then from the solver cache) and
solve time; every time is also given as a ratio to the baseline: scipy SLSQP on a 20-interval
multiple-shooting transcription of the same problem (numpy RK4, finite-difference gradients),
measured in the same process.  Timings depend on machine load.
"""
from __future__ import annotations

import time

import numpy as np
from scipy.optimize import minimize

from solvers.models import reentry_dynamics as dyn
from solvers.models import shuttle as sh
from solvers.reentry import ReentryProblem, simulate_constant_controls, solve
from solvers.transcription import nlp

DEG = sh.DEG
XS = np.array([1e5 * sh.FT_TO_M, 1, 1, 1e4 * sh.FT_TO_M, 1, 1])


def slsqp_baseline(m: int = 20, substeps: int = 4):
    """Max crossrange by SLSQP: z = [T/1000, scaled nodes, controls], FD derivatives."""
    pr = ReentryProblem(intervals=m)
    g = simulate_constant_controls(pr, alpha_rad=17 * DEG, bank_rad=-60 * DEG)
    tau = np.linspace(0, 1, m + 1)
    tf0 = g.t[-1]
    x0 = np.vstack([np.interp(tau, g.t / tf0, r) for r in g.x])
    u0 = np.tile(np.array([[17 * DEG], [-60 * DEG]]), (1, m + 1))
    z0 = np.concatenate([[tf0 / 1000], (x0 / XS[:, None]).ravel(), u0.ravel()])
    n = 6 * (m + 1)

    def unpack(z):
        return z[0] * 1000, z[1:1 + n].reshape(6, m + 1) * XS[:, None], z[1 + n:].reshape(2, m + 1)

    def defects(z):
        T, X, U = unpack(z)
        h = T / m / substeps
        x = X[:, :-1]
        for j in range(substeps):
            a = U[:, :-1] + (U[:, 1:] - U[:, :-1]) * j / substeps
            b = U[:, :-1] + (U[:, 1:] - U[:, :-1]) * (j + 0.5) / substeps
            c = U[:, :-1] + (U[:, 1:] - U[:, :-1]) * (j + 1) / substeps
            k1 = dyn.eom(x, a, sh.SHUTTLE)
            k2 = dyn.eom(x + 0.5 * h * k1, b, sh.SHUTTLE)
            k3 = dyn.eom(x + 0.5 * h * k2, b, sh.SHUTTLE)
            k4 = dyn.eom(x + h * k3, c, sh.SHUTTLE)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return ((x - X[:, 1:]) / XS[:, None]).ravel()

    x0f = np.array(sh.BETTS_INITIAL_STATE) / XS
    xf = np.array([sh.BETTS_TERMINAL["altitude_m"], sh.BETTS_TERMINAL["speed_mps"],
                   sh.BETTS_TERMINAL["flight_path_rad"]]) / XS[[0, 3, 4]]
    bounds = [(0.1, 10)] + [(None, None)] * n + \
        [(-90 * DEG, 90 * DEG)] * (m + 1) + [(-90 * DEG, 1 * DEG)] * (m + 1)
    cons = [{"type": "eq", "fun": defects},
            {"type": "eq", "fun": lambda z: unpack(z)[1][:, 0] / XS - x0f},
            {"type": "eq", "fun": lambda z: (unpack(z)[1][[0, 3, 4], -1]) / XS[[0, 3, 4]] - xf}]
    t0 = time.perf_counter()
    r = minimize(lambda z: -unpack(z)[1][2, -1], z0, method="SLSQP", bounds=bounds,
                 constraints=cons, options={"maxiter": 300, "ftol": 1e-9})
    el = time.perf_counter() - t0
    T, X, _ = unpack(r.x)
    return {"lat": X[2, -1] / DEG, "tf": T, "iters": r.nit, "time": el, "status": r.message}


def main():
    print("Betts shuttle reentry (timings under load from other engineers' jobs on 2 cores)")
    base = slsqp_baseline()
    bt = base["time"]
    print(f"baseline: scipy SLSQP, 20 intervals, FD gradients: lat {base['lat']:.5f} deg, "
          f"tf {base['tf']:.2f} s, {base['iters']} iterations, {bt:.2f} s ({base['status']})")
    hdr = (f"{'preset':<34}{'m':>5}{'lat deg':>11}{'tf s':>10}{'iter':>6}{'build s':>9}"
           f"{'solve s':>9}{'total s':>9}{'total/base':>11}{'warm s':>8}{'warm/base':>10}")
    print(hdr)
    print("-" * len(hdr))
    for name, q in (("betts-max-crossrange", None),
                    ("betts-max-crossrange-heat-limited", sh.BETTS_HEAT_LIMIT_W_M2)):
        for m in (50, 100, 200):
            nlp.clear_cache()
            pr = ReentryProblem(intervals=m, max_heat_rate_w_m2=q)
            t0 = time.perf_counter()
            s = solve(pr)
            cold = time.perf_counter() - t0
            t0 = time.perf_counter()
            solve(pr)
            warm = time.perf_counter() - t0
            st = s.status
            print(f"{name:<34}{m:>5}{s.objective_value / DEG:>11.5f}{s.tf_s:>10.2f}{st.iterations:>6}"
                  f"{st.build_time_s:>9.2f}{st.solve_time_s:>9.2f}{cold:>9.2f}{cold / bt:>11.3f}"
                  f"{warm:>8.2f}{warm / bt:>10.3f}")


if __name__ == "__main__":
    main()
