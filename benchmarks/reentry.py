"""Betts shuttle reentry, the whole ``reentry`` job, against Dymos' own shuttle example, same run.

Run ``python -m benchmarks.reentry`` (``--intervals 100`` for one grid, ``--skip-dymos``).

Ours: the ``reentry`` kind's ``run`` (parameters to problem, solve, verification, result building)
on the ``betts-max-crossrange`` preset at 50, 100 and 200 intervals, each grid in a fresh process
(as a new worker's pool child: the app imported, no solver module yet).  ``cold`` is that process's
first job (the solver modules' import, the CasADi build, IPOPT, the verification, the result);
``warm`` the best of three more jobs (solver cached in the process).  Each is split into build /
IPOPT / verification as the result reports them; the rest is the guess, the result and Python.
Two ways of evaluating IPOPT's derivatives (``solvers.transcription.jit``):

* ``vm``: CasADi's virtual machine (``TRAJLAB_JIT=off``, the default);
* ``jit``: the Hessian and Jacobian compiled to C (``TRAJLAB_JIT=sync``) and loaded from the disk
  cache; the one-time compile of each structure (first process ever) is given on its own line.

Peak RSS is the child's ``ru_maxrss``.

Baseline, the strongest peer that installs: Dymos 1.15.1 (``pip install -e .[bench]``) running its
own shuttle reentry example (``benchmarks.reentry_dymos``: Gauss-Lobatto, 30 segments of order 3,
as in the spec's speed anchors) in a fresh process, timed from problem setup to the optimum.  Its
tests use pyOptSparse's IPOPT/SNOPT, which has no PyPI wheel, so it runs ScipyOptimizeDriver SLSQP,
Dymos' optimizer without pyOptSparse.  Without Dymos the baseline falls back to scipy SLSQP on a
20-interval multiple-shooting transcription (finite differences), measured in this process.
Timings depend on machine load (2 shared cores here): best of the warm runs, one cold run each.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.memory import own_mb
from benchmarks.results import write_results

ROOT = Path(__file__).resolve().parents[1]
GRIDS = (50, 100, 200)


# --- a job in a fresh process ---------------------------------------------------------------------
def child(intervals: int, warm_runs: int = 3) -> dict:
    """One process: a cold job, then ``warm_runs`` warm ones (printed as JSON by ``--child``)."""
    from app.kinds.reentry import PRESETS, run
    from app.kinds.reentry.params import ReentryParams
    from app.service.params import deep_merge
    from app.kinds.base import InProcessContext

    preset = next(p for p in PRESETS if p.name == "betts-max-crossrange")
    params = ReentryParams.model_validate(deep_merge(preset.params, {"grid": {"intervals": intervals}}))

    def job() -> dict:
        t0, c0 = time.perf_counter(), time.process_time()
        out = run(params, InProcessContext())
        total, cpu = time.perf_counter() - t0, time.process_time() - c0
        res = out.result
        return {"total_s": total, "cpu_s": cpu, "build_s": res["solver"]["build_time_s"],
                "ipopt_s": res["solver"]["solve_time_s"], "verify_s": res["verification"]["time_s"],
                "iterations": res["solver"]["iterations"], "lat_deg": res["final"]["latitude_deg"],
                "status": out.status}

    cold = job()
    warm = min((job() for _ in range(warm_runs)), key=lambda r: r["total_s"])
    from solvers.transcription import jit
    return {"intervals": intervals, "cold": cold, "warm": warm, "jit": jit.mode(), "rss_mb": own_mb()}


def in_fresh_process(args: list[str], env: dict | None = None, timeout: float = 1800, cwd=ROOT) -> dict:
    out = subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=cwd,
                         env={**os.environ, "PYTHONPATH": str(ROOT), **(env or {})}, timeout=timeout)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed: {out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


# --- the fallback baseline ------------------------------------------------------------------------
def slsqp_baseline(m: int = 20, substeps: int = 4) -> dict:
    """Max crossrange by scipy SLSQP: z = [T/1000, scaled nodes, controls], FD derivatives."""
    from scipy.optimize import minimize

    from solvers.models import reentry_dynamics as dyn
    from solvers.models import shuttle as sh
    from solvers.reentry import ReentryProblem, simulate_constant_controls

    deg = sh.DEG
    xs = np.array([1e5 * sh.FT_TO_M, 1, 1, 1e4 * sh.FT_TO_M, 1, 1])
    g = simulate_constant_controls(ReentryProblem(intervals=m), alpha_rad=17 * deg, bank_rad=-60 * deg)
    tau = np.linspace(0, 1, m + 1)
    tf0 = g.t[-1]
    x0 = np.vstack([np.interp(tau, g.t / tf0, r) for r in g.x])
    u0 = np.tile(np.array([[17 * deg], [-60 * deg]]), (1, m + 1))
    z0 = np.concatenate([[tf0 / 1000], (x0 / xs[:, None]).ravel(), u0.ravel()])
    n = 6 * (m + 1)

    def unpack(z):
        return z[0] * 1000, z[1:1 + n].reshape(6, m + 1) * xs[:, None], z[1 + n:].reshape(2, m + 1)

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
        return ((x - X[:, 1:]) / xs[:, None]).ravel()

    x0f = np.array(sh.BETTS_INITIAL_STATE) / xs
    xf = np.array([sh.BETTS_TERMINAL["altitude_m"], sh.BETTS_TERMINAL["speed_mps"],
                   sh.BETTS_TERMINAL["flight_path_rad"]]) / xs[[0, 3, 4]]
    bounds = [(0.1, 10)] + [(None, None)] * n + [(-90 * deg, 90 * deg)] * (m + 1) + [(-90 * deg, 1 * deg)] * (m + 1)
    cons = [{"type": "eq", "fun": defects},
            {"type": "eq", "fun": lambda z: unpack(z)[1][:, 0] / xs - x0f},
            {"type": "eq", "fun": lambda z: (unpack(z)[1][[0, 3, 4], -1]) / xs[[0, 3, 4]] - xf}]
    t0, c0 = time.perf_counter(), time.process_time()
    r = minimize(lambda z: -unpack(z)[1][2, -1], z0, method="SLSQP", bounds=bounds, constraints=cons,
                 options={"maxiter": 300, "ftol": 1e-9})
    el, cpu = time.perf_counter() - t0, time.process_time() - c0
    T, X, _ = unpack(r.x)
    return {"name": f"scipy SLSQP, {m} intervals, FD gradients", "total_s": el, "cpu_s": cpu, "lat_deg": X[2, -1] / deg,
            "tf_s": T, "iterations": int(r.nit), "rss_mb": own_mb()}


def baseline(skip_dymos: bool) -> dict:
    if not skip_dymos:
        try:
            import dymos  # noqa: F401
        except ImportError:
            print("Dymos is not installed (pip install -e .[bench]): scipy SLSQP baseline instead")
        else:
            with tempfile.TemporaryDirectory() as tmp:   # OpenMDAO writes its reports into the cwd
                d = in_fresh_process(["-m", "benchmarks.reentry_dymos", "30"], cwd=tmp)
            d["name"] = "Dymos 1.15.1 shuttle example, Gauss-Lobatto 30x3, ScipyOptimizeDriver SLSQP"
            return d
    return slsqp_baseline()


# --- the table ------------------------------------------------------------------------------------
def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--intervals", type=int, nargs="*", default=list(GRIDS))
    ap.add_argument("--skip-dymos", action="store_true")
    a = ap.parse_args()
    if a.child:
        print(json.dumps(child(a.child)))
        return
    print("Betts shuttle reentry, max crossrange: the whole reentry job (run) in a fresh process "
          "(2 shared cores, other work running: one cold run, best of 3 warm)")
    base = baseline(a.skip_dymos)
    bt = base["total_s"]
    print(f"baseline: {base['name']}: lat {base['lat_deg']:.5f} deg, tf {base['tf_s']:.2f} s, "
          f"{base.get('iterations', '?')} iterations, {bt:.2f} s setup+solve "
          f"({base.get('cpu_s', float('nan')):.2f} s CPU), peak RSS {base['rss_mb']:.0f} MB")
    figures = {"baseline": base, "rows": []}
    hdr = (f"{'mode':<5}{'m':>5}{'lat deg':>11}{'it':>4}  {'cold s':>7}{'build':>7}{'ipopt':>7}{'verif':>7}"
           f"{'cold/base':>10}  {'warm s':>7}{'ipopt':>7}{'verif':>7}{'warm/base':>10}{'RSS MB':>8}")
    print(hdr)
    print("-" * len(hdr))
    with tempfile.TemporaryDirectory() as cache:
        for mode in ("vm", "jit"):
            env = {"TRAJLAB_JIT": "off" if mode == "vm" else "sync", "TRAJLAB_JIT_CACHE": cache}
            for m in a.intervals:
                if mode == "jit":
                    t0 = time.perf_counter()
                    first = in_fresh_process(["-m", "benchmarks.reentry", "--child", str(m)], env)
                    print(f"{'jit':<5}{m:>5}  one-time compile of this structure: first job "
                          f"{first['cold']['total_s']:.1f} s (build {first['cold']['build_s']:.1f} s), "
                          f"process {time.perf_counter() - t0:.1f} s")
                    figures["rows"].append({"mode": "jit-first-compile", **first})
                r = in_fresh_process(["-m", "benchmarks.reentry", "--child", str(m)], env)
                c, w = r["cold"], r["warm"]
                print(f"{mode:<5}{m:>5}{w['lat_deg']:>11.5f}{w['iterations']:>4}  {c['total_s']:>7.3f}"
                      f"{c['build_s']:>7.3f}{c['ipopt_s']:>7.3f}{c['verify_s']:>7.3f}{c['total_s'] / bt:>10.4f}"
                      f"  {w['total_s']:>7.3f}{w['ipopt_s']:>7.3f}{w['verify_s']:>7.3f}{w['total_s'] / bt:>10.4f}"
                      f"{r['rss_mb']:>8.0f}")
                figures["rows"].append({"mode": mode, **r, "cold_over_baseline": c["total_s"] / bt,
                                        "warm_over_baseline": w["total_s"] / bt,
                                        "warm_cpu_over_baseline_cpu": w["cpu_s"] / base.get("cpu_s", np.nan)})
    print(f"targets (100 intervals): whole job warm < 0.5 s, cold < 1 s; baseline RSS {base['rss_mb']:.0f} MB")
    write_results("reentry", figures)


if __name__ == "__main__":
    main()
