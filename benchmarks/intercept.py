"""Finite-thrust fuel-optimal interception (paper 003, method I): three transcriptions, same run.

Run ``python -m benchmarks.intercept``.  One scenario (spec ``intercept.md``: interceptor and
circular target as printed, 500 kg, Isp 300 s, 2000 N, g0 = 9.80665, fixed tf = 8080.5 s), one
warm start (the impulsive Lambert optimum, scanned at 5 s), three methods:

1. the paper's formulation: one 60-node LGL segment with a free throttle (differential form);
2. trajlab's default: coast/burn arcs with free switch times on integral-form LGL, burns added
   where the switching function asks for them, segments refined until the re-propagated miss
   is below 100 m (:mod:`solvers.intercept.thrust`);
3. the baseline: direct multiple shooting on 200 equal intervals with piecewise-constant
   throttle and direction, RK4 inside each interval (:mod:`solvers.transcription.multiple_shooting`).

Columns: the outcome (for the LGL rows the solver's verdict after its own re-propagation check;
IPOPT's word is printed below the table), IPOPT iterations (summed over meshes), fuel from the
transcription's own final mass, and the miss distance at tf when the optimal controls are
re-propagated (DOP853, rtol 1e-10, inertial two-body for both bodies, the controls interpolated
exactly as the transcription defines them): the same routine for every row, so a small fuel bought
with a large miss shows up.  ``cold s`` is one whole call (warm-start propagation, CasADi build,
IPOPT, re-propagation) with the solver cache empty; ``warm s`` the same call again with the built
solver taken from the cache.  ``build s`` / ``IPOPT s`` split the cold call.  Ratios are against
the baseline's cold and warm times measured here.  Timings depend on machine load (2 cores).
Last, the peak memory (RSS) of a whole intercept job in a fresh process against a bare
``import numpy, casadi`` (written to ``benchmarks/results/latest.json`` under ``intercept``).

Started from the single impulse, the baseline keeps a single burn (a local optimum); trajlab's
method adds the short burn at t = 0 that the switching function asks for, which is most of the
fuel difference between the two rows.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from solvers.intercept import InterceptProblem, ScanSettings, solve_impulsive
from solvers.intercept.cases import PAPER_003, REFERENCE_FUEL_KG
from solvers.intercept.thrust import (FiniteThrustProblem, ImpulsiveGuess, MeshOptions, nondimensionalise,
                                      plan_impulsive, propagate_hill, solve_finite_thrust, verify_controls)
from solvers.models import relative_motion as rm
from solvers.transcription import nlp
from solvers.transcription.lgl import Mesh
from solvers.transcription.multiple_shooting import PathConstraint, ShootingProblem, Transcription

MS_INTERVALS = 200
MS_SUBSTEPS = 4              # 10 s RK4 steps (n h = 0.011): the DOP853 re-propagation agrees to < 1 m
MS_MAX_ITERATIONS = 1000
BASELINE_BUDGET_S = 120.0    # cold + warm baseline; each IPOPT call gets half (max_wall_time)


def _problem(**kw) -> FiniteThrustProblem:
    return FiniteThrustProblem(scenario=PAPER_003, **kw)


def _impulsive_guess() -> tuple[ImpulsiveGuess, float]:
    t0 = time.perf_counter()
    sol = solve_impulsive(InterceptProblem(PAPER_003, scan=ScanSettings(step_s=5.0, retrograde=False)))
    if not sol.status.ok:
        raise SystemExit(f"impulsive warm start failed: {sol.status.message}")
    return ImpulsiveGuess(sol.best_t_man_s, sol.delta_v_vector_mps), time.perf_counter() - t0


# ----------------------------------------------------------------------------- baseline

def _shooting_structure() -> ShootingProblem:
    """Max final mass, relative position zero at tf, on the nondimensional Hill model.

    The states and time are already O(1) after nondimensionalisation (length: target radius,
    time: 1/n), so the transcription's scales are all one.  ``|d| <= 1`` is a node path
    constraint; with piecewise-constant controls every interval's control is a node value.
    """
    return ShootingProblem(
        key=("benchmark_intercept_ms",), nx=rm.NX, nu=rm.NU, n_params=2,
        dynamics=lambda x, u, p: rm.dynamics_casadi(x, u, p[0], p[1]),
        x_scale=[1.0] * rm.NX, u_scale=[1.0] * rm.NU, t_scale=1.0,
        intervals=MS_INTERVALS, control="constant", substeps=MS_SUBSTEPS,
        mayer=lambda xf, T, p: -xf[6],
        path=(PathConstraint("direction", lambda x, u, p: ca.sumsqr(u[1:]) - 1.0),),
        terminal=lambda xf, p: xf[:3], n_terminal=3,
        # the same stopping rule as the LGL solvers, so iterations are comparable
        ipopt={"max_iter": MS_MAX_ITERATIONS, "tol": 1e-9, "acceptable_tol": 1e-7, "acceptable_iter": 10,
               # keeps the whole benchmark under ~3 minutes if IPOPT stalls (the outcome then says so)
               "max_wall_time": BASELINE_BUDGET_S / 2},
    )


def _shooting_guess(problem: FiniteThrustProblem, guess: ImpulsiveGuess):
    """The impulsive optimum spread over the intervals it overlaps (throttle = overlap fraction,
    so the guess burns the impulse's propellant), states propagated under those controls."""
    s = nondimensionalise(problem)
    plan = plan_impulsive(guess, problem=problem, s=s, tf=s.tf)
    t = np.linspace(0.0, s.tf, MS_INTERVALS + 1)
    u = np.zeros((rm.NU, MS_INTERVALS))
    for a, b in plan.windows:
        u[0] += np.clip(np.minimum(t[1:], b) - np.maximum(t[:-1], a), 0.0, None) / np.diff(t)
    u[1:] = plan.direction(0.5 * (t[1:] + t[:-1]))

    def control(tt):
        k = min(int(np.searchsorted(t, tt, side="right")) - 1, MS_INTERVALS - 1)
        return u[0, k], u[1:, k]

    x = propagate_hill(s, t, control, breaks=t[1:-1])
    return s, t, x, u


def _repropagate_constant(problem: FiniteThrustProblem, s, x: np.ndarray, u: np.ndarray, tf: float) -> dict:
    """The miss of piecewise-constant controls, by the same routine as the LGL rows.

    ``verify_controls`` interpolates per-segment Lagrange polynomials through node values; a segment
    whose 3 nodes carry the same control is that constant, so the baseline's controls go
    through it unchanged.  Only the last state column is read (for the propellant).
    """
    mesh = Mesh.uniform(MS_INTERVALS, 3)
    return verify_controls(problem, s=s, mesh=mesh, X=np.repeat(x[:, 1:], 3, axis=1), U=np.repeat(u, 3, axis=1), tf=tf)


def solve_multiple_shooting(problem: FiniteThrustProblem, guess: ImpulsiveGuess) -> dict:
    s, t, x0, u0 = _shooting_guess(problem, guess)
    tr = Transcription(_shooting_structure())
    x_lb = np.tile(np.array([-50.0] * 6 + [s.m_dry])[:, None], (1, MS_INTERVALS + 1))
    x_ub = np.tile(np.array([50.0] * 6 + [1.0])[:, None], (1, MS_INTERVALS + 1))
    x_lb[:, 0] = x_ub[:, 0] = s.x0
    res = tr.solve(p=[s.tmax, s.c], x_lb=x_lb, x_ub=x_ub, u_lb=[0.0, -1.0, -1.0, -1.0], u_ub=[1.0] * 4,
                   tf_bounds=(s.tf, s.tf), guess=(s.tf, x0, u0), terminal_bounds=(np.zeros(3), np.zeros(3)),
                   expected_iterations=200)
    ver = _repropagate_constant(problem, s, res.x, res.u, res.tf)
    ts = res.t * s.sc.time_s
    on = res.u[0] > 0.5
    burns = []
    for k in np.flatnonzero(on & ~np.r_[False, on[:-1]]):
        j = k
        while j + 1 < on.size and on[j + 1]:
            j += 1
        burns.append({"start_s": float(ts[k]), "end_s": float(ts[j + 1])})
    st = res.status
    return {"status": st, "build_s": 0.0 if res.was_cached else tr.solver.build_time_s,
            "ipopt_s": st.solve_time_s, "fuel_kg": float((1.0 - res.x[6, -1]) * problem.scenario.mass_kg),
            "miss_m": ver["miss_distance_m"], "burns": burns,
            "partial_throttle_intervals": int(np.sum((res.u[0] > 1e-3) & (res.u[0] < 1 - 1e-3)))}


# ----------------------------------------------------------------------------- LGL rows

def _solve_lgl(mesh: MeshOptions, guess: ImpulsiveGuess) -> dict:
    sol = solve_finite_thrust(_problem(mesh=mesh), initial_guess=guess)
    st = sol.status
    return {"status": st, "build_s": st.build_time_s, "ipopt_s": st.solve_time_s, "fuel_kg": sol.fuel_kg,
            "miss_m": sol.verification.get("miss_distance_m", float("nan")),
            "burns": [{"start_s": b["start_s"], "end_s": b["end_s"]} for b in sol.burns],
            "rounds": len(sol.history)}


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _load_ipopt() -> None:
    """Build and solve a one-variable NLP so that loading the IPOPT plugin (a one-off
    dlopen of ~0.3 s) is not charged to whichever method happens to run first."""
    x = ca.SX.sym("x")
    ca.nlpsol("load", "ipopt", {"x": x, "f": (x - 1) ** 2},
              {"ipopt": {"print_level": 0, "sb": "yes"}, "print_time": False})(x0=0)


def _cold_and_warm(fn) -> tuple[dict, float, float]:
    nlp.clear_cache()
    out, cold = _timed(fn)
    _, warm = _timed(fn)       # same structure again: the built solver comes from the cache
    return out, cold, warm


def _fmt_burns(burns: list[dict]) -> str:
    return ", ".join(f"{b['start_s']:.1f}-{b['end_s']:.1f}" for b in burns) or "none"


def main() -> None:
    guess, imp_s = _impulsive_guess()
    _load_ipopt()
    paper = MeshOptions(structure="free_throttle", segments=1, nodes=60, refine=False, max_iterations=3000)
    base, base_cold, base_warm = _cold_and_warm(lambda: solve_multiple_shooting(_problem(), guess))
    rows = [
        ("paper: single-segment LGL, 60 nodes, free throttle", *_cold_and_warm(lambda: _solve_lgl(paper, guess))),
        ("ours: switching structure, integral LGL, refined", *_cold_and_warm(lambda: _solve_lgl(MeshOptions(), guess))),
        (f"baseline: multiple shooting, {MS_INTERVALS} intervals", base, base_cold, base_warm),
    ]

    print("paper 003 method I: fuel-optimal finite-thrust interception, fixed tf = 8080.5 s, g0 = 9.80665 m/s^2")
    print(f"warm start for every method: impulsive optimum, dv {np.linalg.norm(guess.delta_v_mps):.2f} m/s at "
          f"t_man {guess.t_man_s:.1f} s ({imp_s:.2f} s, not counted below); timings under machine load, 2 cores\n")
    hdr = (f"{'method':<52}{'outcome':>14}{'iter':>6}{'fuel kg':>9}{'miss m':>11}{'build s':>9}{'IPOPT s':>9}"
           f"{'cold s':>8}{'cold/base':>10}{'warm s':>8}{'warm/base':>10}")
    print(hdr)
    print("-" * len(hdr))
    for name, r, cold, warm in rows:
        st = r["status"]
        print(f"{name:<52}{st.outcome.value:>14}{st.iterations:>6}{r['fuel_kg']:>9.2f}{r['miss_m']:>11.2f}"
              f"{r['build_s']:>9.2f}{r['ipopt_s']:>9.2f}{cold:>8.2f}{cold / base_cold:>10.3f}"
              f"{warm:>8.2f}{warm / base_warm:>10.3f}")
    print()
    for name, r, _, _ in rows:
        st = r["status"]
        extra = f", meshes solved: {r['rounds']}" if "rounds" in r else \
            f", intervals at partial throttle: {r['partial_throttle_intervals']}"
        print(f"{name.split(':')[0]:<9} IPOPT {st.solver_status}{extra}; burns (s): {_fmt_burns(r['burns'])}")
        if "warning" in st.details:
            print(f"{'':<9} {st.details['warning']}")
    print(f"\nspec reference: {REFERENCE_FUEL_KG} kg from {MS_INTERVALS}-interval multiple shooting in about 72 s")
    if base["status"].solver_status == "Maximum_WallTime_Exceeded":
        print(f"the baseline needs more than {BASELINE_BUDGET_S / 2:.0f} s per solve: IPOPT was stopped there "
              f"(cap, to keep the benchmark near 3 minutes); its row is the unconverged iterate")


def job_memory() -> dict:
    """Peak RSS of a whole intercept job (the kind's default preset, impulsive + finite thrust, in a
    fresh process as a worker's child runs it), against a bare ``import numpy, casadi`` process
    (:func:`benchmarks.job_memory.job_figures`)."""
    from benchmarks.job_memory import job_figures

    r = job_figures("intercept")
    print(f"\njob memory: intercept preset {r['job_preset']} ({r['job_status']}, {r['job_cold_s']:.2f} s cold in a "
          f"fresh process): peak RSS {r['job_peak_rss_mb']:.0f} MB, {r['job_rss_ratio']:.2f}x the "
          f"{r['baseline_peak_rss_mb']:.0f} MB of python -c \"{r['baseline']}\"")
    return r


if __name__ == "__main__":
    from benchmarks.results import write_results

    main()
    write_results("intercept", job_memory())
