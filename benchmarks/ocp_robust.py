"""Robust ``ocp`` design benchmark (issue 37 item 6): each robust preset against its deterministic twin on the same
grid, and its Monte Carlo, in one process.

    python -m benchmarks.ocp_robust [--samples 10000] [--only bryson-denham-robust,...] [--no-save]

Rows per robust preset (wall seconds of this process, CasADi's virtual machine, the machine's load included; 2
shared cores: compare the ratios, not the seconds):
* twin: the deterministic twin's solve on the preset's grid, warm (its NLP already built in this process);
* robust: one robust solve (the augmented NLP warm-started from the twin, its tighten rounds), warm likewise; the
  robust job's solves are the twin's plus this, so ``ratio`` = (twin + robust) / twin; target within
  :data:`TARGET_RATIO` (issue 37);
* job: the whole robust job as the service runs it, warm (:func:`solvers.ocp.robust.solver.design_and_confirm`
  with the preset's own Monte Carlo size in this process: twin, robust NLP, Monte Carlo, and the confirmation
  rounds that raise the limits' k), against the twin's solve: ``job ratio`` = job / twin;
* Monte Carlo: ``--samples`` re-flights of the design in one process (the chunk function the workers run:
  :func:`solvers.uncertainty.montecarlo.run_monte_carlo`), target seconds (:data:`TARGET_MC_S`), with the
  draws per second.
Figures go to ``benchmarks/results/latest.json`` under ``ocp_robust``.  The public API only, as a user would
(``solvers.ocp``, ``solvers.ocp.robust.solver``).
"""
from __future__ import annotations

import argparse
import os
import time

from solvers.ocp import PRESETS, parse_problem, solve
from solvers.ocp.robust.solver import design_and_confirm, solve_robust
from solvers.uncertainty.montecarlo import run_monte_carlo

ROBUST = [n for n, p in PRESETS.items() if "uncertainty" in p["params"]]
TARGET_RATIO = 3.0      # the robust job's solves against its twin's (issue 37 item 6)
TARGET_MC_S = 10.0      # "seconds" for 10,000 draws


def row(name: str, samples: int) -> dict:
    body = PRESETS[name]["params"]
    problem = parse_problem(body)
    twin = {k: v for k, v in body.items() if k not in ("uncertainty", "robust")}
    solve(parse_problem(twin))                                   # builds the twin's NLP
    t = time.perf_counter()
    det = solve(parse_problem(twin))
    t_det = time.perf_counter() - t
    solve_robust(problem, params=body, deterministic=det)        # builds the robust NLP
    t = time.perf_counter()
    rs = solve_robust(problem, params=body, deterministic=det)
    t_rob = time.perf_counter() - t
    t = time.perf_counter()
    summary = run_monte_carlo(rs.monte_carlo_spec, samples, 1)
    t_mc = time.perf_counter() - t
    obj = summary["terminal"].get("objective", {})
    ratio = (t_det + t_rob) / t_det
    t = time.perf_counter()
    answer, block, _ = design_and_confirm(parse_problem(body), params=body, run_monte_carlo=run_monte_carlo)
    t_job = time.perf_counter() - t
    return {"preset": name, "twin_s": t_det, "robust_s": t_rob, "ratio": ratio, "ratio_met": ratio <= TARGET_RATIO,
            "twin_iterations": det.status.iterations, "robust_iterations": rs.timing.get("robust_iterations"),
            "limit_rounds": rs.timing.get("limit_rounds"), "job_s": t_job, "job_ratio": t_job / t_det,
            "job_rounds": len(block["rounds"]) if block else None, "confirmed": bool(block and block["confirmed"]),
            "mc_samples": samples, "mc_s": t_mc,
            "mc_draws_per_s": samples / t_mc, "mc_met": t_mc <= TARGET_MC_S,
            "det_objective": det.objective, "robust_objective": rs.solution.objective,
            # the job's answer (the docs' table of robust presets): its last round's design and constraints' k
            "job_objective": answer.solution.objective, "job_k_constraints": block["k_constraints"] if block else None,
            "cadet_mean": rs.prediction["objective"]["mean"], "cadet_std": rs.prediction["objective"]["std"],
            "mc_mean": obj.get("mean"), "mc_std": obj.get("std")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--only", default=",".join(ROBUST), help="comma-separated robust presets")
    ap.add_argument("--no-save", action="store_true", help="keep the figures out of benchmarks/results/latest.json")
    args = ap.parse_args()
    names = [n for n in args.only.split(",") if n]
    unknown = [n for n in names if n not in ROBUST]
    if unknown:
        raise SystemExit(f"not a robust preset: {', '.join(unknown)} (robust: {', '.join(ROBUST)})")
    print(f"robust ocp job against its deterministic twin on the same grid (target {TARGET_RATIO:g}x) and "
          f"{args.samples} Monte Carlo draws (target {TARGET_MC_S:g} s); load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores")
    print(f"{'preset':<40}{'twin s':>8}{'it':>5}{'robust s':>10}{'it':>5}{'ratio':>7}{'':>8}{'job s':>8}{'rounds':>7}"
          f"{'job ratio':>10}{'MC s':>8}{'draws/s':>9}{'':>8}")
    figures = {}
    for name in names:
        r = row(name, args.samples)
        figures[name] = r
        print(f"{name:<40}{r['twin_s']:>8.2f}{r['twin_iterations']:>5}{r['robust_s']:>10.2f}"
              f"{r['robust_iterations']:>5}{r['ratio']:>7.2f}{'met' if r['ratio_met'] else 'MISSED':>8}"
              f"{r['job_s']:>8.2f}{r['job_rounds']:>7}{r['job_ratio']:>10.2f}"
              f"{r['mc_s']:>8.2f}{r['mc_draws_per_s']:>9.0f}{'met' if r['mc_met'] else 'MISSED':>8}", flush=True)
    print("\n(robust J: one robust solve at the k posed; the job's answer may be a later round's)")
    print(f"{'preset':<40}{'twin J':>12}{'robust J':>12}{'cost':>11}{'CADET mean':>12}{'MC mean':>12}"
          f"{'CADET std':>11}{'MC std':>11}")
    for name, r in figures.items():
        print(f"{name:<40}{r['det_objective']:>12.6g}{r['robust_objective']:>12.6g}"
              f"{r['robust_objective'] - r['det_objective']:>11.4g}{r['cadet_mean']:>12.6g}{r['mc_mean']:>12.6g}"
              f"{r['cadet_std']:>11.4g}{r['mc_std']:>11.4g}")
    if not args.no_save:
        from benchmarks.results import write_results
        write_results("ocp_robust", figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
