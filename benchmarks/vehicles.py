"""Vehicle models as data: what an aero table and a table atmosphere cost against the polynomial
shuttle, same process.

Run ``python -m benchmarks.vehicles``.  Baseline: the Betts max-crossrange case with the
polynomial shuttle at 100 intervals (the peer at its strongest: the model the benchmark was
written for).  Rows: the same case with the aero table sampled from the polynomials (36 alpha
breakpoints, no Mach axis), the same with a 4-point Mach axis, and the Mars MSL preset (2-D
aero tables, log-density and speed-of-sound table atmosphere).  Build: cold (solver cache
cleared); solve and verification: best of ``REPEATS`` from the cache.  Times depend on machine load.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from benchmarks.results import write_results
from solvers.models import shuttle as sh
from solvers.models.aerodynamics import sample_polynomials
from solvers.reentry import ReentryProblem, solve
from solvers.transcription import nlp

REPEATS = 3


def _mars_problem() -> ReentryProblem:
    from app.kinds import KINDS, PRESETS
    from app.kinds.reentry.edge import to_problem
    spec = KINDS["reentry"]
    return to_problem(spec.params_model.model_validate(PRESETS["mars-msl-max-crossrange"].params))


def _case(problem: ReentryProblem) -> dict:
    nlp.clear_cache()
    s = solve(problem)
    build = s.status.build_time_s
    best = min((solve(problem) for _ in range(REPEATS)), key=lambda r: r.status.solve_time_s)
    return {"objective_deg": float(np.degrees(s.objective_value)), "status": s.status.solver_status,
            "iterations": int(best.status.iterations), "build_s": float(build),
            "solve_s": float(best.status.solve_time_s),
            "verify_s": float(best.status.details.get("verification_time_s", float("nan")))}


def main() -> None:
    alpha = np.arange(-90.0, 90.1, 5.0)
    poly = sh.SHUTTLE
    table_1d = dataclasses.replace(poly, aero_table=sample_polynomials(
        cl_coeffs=poly.cl_coeffs, cd_coeffs=poly.cd_coeffs, alpha_deg=alpha))
    table_2d = dataclasses.replace(poly, aero_table=sample_polynomials(
        cl_coeffs=poly.cl_coeffs, cd_coeffs=poly.cd_coeffs, alpha_deg=alpha, mach=(0.5, 5.0, 15.0, 40.0)))
    rows = {"betts polynomial (baseline)": _case(ReentryProblem(vehicle=poly)),
            "betts aero table (alpha)": _case(ReentryProblem(vehicle=table_1d)),
            "betts aero table (alpha x Mach)": _case(ReentryProblem(vehicle=table_2d)),
            "mars msl preset": _case(_mars_problem())}
    base = rows["betts polynomial (baseline)"]
    print(f"{'case':34s} {'objective':>10s} {'iter':>5s} {'build s':>8s} {'solve s':>8s} {'x base':>7s} "
          f"{'verify s':>9s}")
    figures = {}
    for name, r in rows.items():
        ratio = r["solve_s"] / base["solve_s"]
        print(f"{name:34s} {r['objective_deg']:10.5f} {r['iterations']:5d} {r['build_s']:8.3f} "
              f"{r['solve_s']:8.3f} {ratio:7.2f} {r['verify_s']:9.3f}")
        figures[name] = {**r, "solve_ratio_to_polynomial": ratio}
    write_results("vehicles", figures)


if __name__ == "__main__":
    main()
