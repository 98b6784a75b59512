"""Robust ``ocp`` design benchmark (issue 37 item 6): each robust preset against its deterministic twin, and its
Monte Carlo, in one run.

    python -m benchmarks.ocp_robust [--samples 10000]

Rows per robust preset (wall seconds of this process, CasADi's virtual machine, the machine's load included):
* twin: the deterministic twin's solve on the preset's grid, warm (its NLP already built in this process);
* robust NLP: one robust solve (the augmented NLP warm-started from the twin, its tighten rounds); the robust
  job's solves are the twin's plus this, so ``ratio`` = (twin + robust) / twin (target within 3x);
* Monte Carlo: ``--samples`` re-flights of the design in one process (the chunk function the workers run:
  :func:`solvers.uncertainty.montecarlo.simulate_chunk`), target seconds.
The public API only, as a user would (``solvers.ocp``, ``solvers.ocp.robust.solver``).
"""
from __future__ import annotations

import argparse
import time

from solvers.ocp import PRESETS, parse_problem, solve
from solvers.ocp.robust.solver import solve_robust
from solvers.uncertainty.montecarlo import run_monte_carlo

ROBUST = [n for n, p in PRESETS.items() if "uncertainty" in p["params"]]


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
    run_monte_carlo(rs.monte_carlo_spec, samples, 1)
    t_mc = time.perf_counter() - t
    return {"preset": name, "twin_s": t_det, "robust_s": t_rob, "ratio": (t_det + t_rob) / t_det, "mc_s": t_mc,
            "det_objective": det.objective, "robust_objective": rs.solution.objective}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=10_000)
    args = ap.parse_args()
    print(f"{'preset':42s} {'twin s':>8s} {'robust s':>9s} {'ratio':>6s} {'MC s':>7s}  ({args.samples} draws)")
    for name in ROBUST:
        r = row(name, args.samples)
        print(f"{r['preset']:42s} {r['twin_s']:8.2f} {r['robust_s']:9.2f} {r['ratio']:6.2f} {r['mc_s']:7.2f}")


if __name__ == "__main__":
    main()
