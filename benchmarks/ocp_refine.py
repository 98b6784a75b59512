"""Mesh refinement against uniform grids (issue 26 item 5): the row ``benchmarks.ocp`` prints last.

For each problem and transcription (brachistochrone by multiple shooting and by LGL, Betts' shuttle
by multiple shooting) and the accuracy 1e-6 (the re-flown states within 1e-6 of each state's scale):

* **refined**: :func:`solvers.ocp.solve` with ``accuracy`` from a coarse grid (``START``), cold
  (solver cache and symbolic functions cleared), every round counted: build, IPOPT, the DOP853
  re-flight and, for rounds not accepted, the per-interval re-flight of the error estimate;
* **uniform**: the smallest number of equal intervals whose answer re-flies within the accuracy
  (doubling from the refined start, then bisection; each probe a plain solve without ``accuracy``),
  then that grid solved cold as a user who knew it would, build + IPOPT + its re-flight.  The
  uniform solves keep the preset's RK4 steps: the terminal check's own refinement (twice the
  substeps on a missed final value, :data:`solvers.ocp.solver.TERMINAL_ROUNDS`) is off for them,
  else "50 intervals" would be 50 intervals of 4 steps (the shuttle's gamma misses by 1e-6 rad at 2).

The refined solve must reach the accuracy with fewer intervals and in less time.  Times are best of
``reps``; this machine's 2 shared cores make single runs noisy (the load average is printed).
"""
from __future__ import annotations

import copy
import os
import time
from collections.abc import Callable

import solvers.ocp.solver as ocp_solver
from solvers.ocp import PRESETS, parse_problem, solve
from solvers.ocp.symbolic import reset_caches
from solvers.transcription.nlp import clear_cache

ACCURACY = 1e-6
# (preset, transcription method) -> the coarse grid the refinement starts from
START = {("brachistochrone", "multiple_shooting"): 4, ("brachistochrone", "lgl"): 4,
         ("betts-shuttle-ocp", "multiple_shooting"): 50}


def _params(case, intervals: int, accuracy: float | None) -> dict:
    name, method = case
    params = copy.deepcopy(PRESETS[name]["params"])
    params["transcription"].update(method=method, intervals=intervals)
    if accuracy is not None:
        params["accuracy"] = accuracy
    return params


def solve_as_given(params: dict):
    """``solve``; without ``accuracy`` on the grid as given (no terminal-miss substep rounds)."""
    rounds = ocp_solver.TERMINAL_ROUNDS
    if params.get("accuracy") is None:
        ocp_solver.TERMINAL_ROUNDS = 0
    try:
        return solve(parse_problem(params))
    finally:
        ocp_solver.TERMINAL_ROUNDS = rounds


def cold(params: dict):
    """``(solution, seconds)`` of :func:`solve_as_given` on ``params``, cold: the solver cache and the
    symbolic functions cleared first, so the time counts every build."""
    reset_caches()
    clear_cache()
    t = time.perf_counter()
    sol = solve_as_given(params)
    return sol, time.perf_counter() - t


def _error(sol) -> float:
    return float(sol.verification["max_state_difference_scaled_overall"])


def smallest_grid(ok: Callable[[int], bool], start: int, *, cap: int) -> tuple[int | None, int]:
    """``(N, probes)``: the fewest equal intervals ``N`` with ``ok(N)`` found (None when none up to ``cap``):
    from ``start``, halving down while ``ok`` holds or doubling up until it does, then bisection between the
    last miss and the first hit.  ``ok`` need not be monotone in ``N`` (where a bang-bang switch falls inside
    an interval matters), so the bisection finds *a* small grid, not always the smallest."""
    probes = 0

    def probe(n: int) -> bool:
        nonlocal probes
        probes += 1
        return ok(n)

    hi = start
    if probe(hi):                       # halve down to a grid that misses
        lo = hi // 2
        while lo >= 2 and probe(lo):
            lo, hi = lo // 2, lo
    else:                               # double up to one that reaches it
        lo = hi
        while True:
            if hi >= cap:
                return None, probes
            lo, hi = hi, min(2 * hi, cap)
            if probe(hi):
                break
    while hi - lo > 1:                  # ok(hi), not ok(lo)
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if probe(mid) else (mid, hi)
    return hi, probes


def smallest_uniform(name, start: int, accuracy: float, *, cap: int = 1000) -> tuple[int, int]:
    """``(N, probes)``: the fewest equal intervals whose re-flight is within ``accuracy`` (``cap`` when none)."""
    def ok(n: int) -> bool:
        sol = solve_as_given(_params(name, n, None))
        return sol.status.ok and _error(sol) <= accuracy

    n, probes = smallest_grid(ok, start, cap=cap)
    return (cap if n is None else n), probes


def refinement_rows(names=tuple(START), reps: int = 1) -> dict:
    print(f"\nmesh refinement to {ACCURACY:g} (re-flown states, scaled) against the smallest uniform grid "
          f"that reaches it; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'problem':<19}{'method':<7}{'form':<9}{'rounds':>7}{'intervals':>10}{'nodes':>6}{'error':>10}"
          f"{'iter':>6}{'time s':>8}{'objective':>14}  mesh")
    figures = {}
    for name in names:
        runs = [cold(_params(name, START[name], ACCURACY)) for _ in range(reps)]
        sol, t_ref = min(runs, key=lambda r: r[1])
        rounds = sol.solver["refinement"]
        n_uni, probes = smallest_uniform(name, START[name], ACCURACY)
        uni = [cold(_params(name, n_uni, None)) for _ in range(reps)]
        usol, t_uni = min(uni, key=lambda r: r[1])
        path = " -> ".join(str(r["intervals"]) for r in rounds)
        if sol.solver.get("segment_nodes"):
            path += f" (nodes per interval {sol.solver['segment_nodes']})"
        method = "MS" if name[1] == "multiple_shooting" else "LGL"
        nodes, unodes = len(sol.trajectory["t"]), len(usol.trajectory["t"])
        print(f"{name[0]:<19}{method:<7}{'refined':<9}{len(rounds) - 1:>7}{sol.solver['intervals']:>10}{nodes:>6}"
              f"{_error(sol):>10.2e}{sol.solver['iterations']:>6}{t_ref:>8.2f}{sol.objective:>14.8g}  {path}")
        print(f"{'':<26}{'uniform':<9}{'':>7}{n_uni:>10}{unodes:>6}{_error(usol):>10.2e}{usol.solver['iterations']:>6}"
              f"{t_uni:>8.2f}{usol.objective:>14.8g}  smallest of {probes} probes")
        fewer, faster = sol.solver["intervals"] < n_uni, t_ref < t_uni
        print(f"{'':<26}target: fewer intervals {'met' if fewer else 'MISSED'}, less time "
              f"{'met' if faster else 'MISSED'} ({t_ref / t_uni:.2f}x)")
        figures[f"{name[0]} {method}"] = {"accuracy": ACCURACY, "start_intervals": START[name],
                         "refined": {"rounds": rounds, "intervals": sol.solver["intervals"], "error": _error(sol),
                                     "iterations": sol.solver["iterations"], "time_s": t_ref,
                                     "objective": sol.objective, "reached": (sol.solver.get("accuracy") or {}).get("reached"),
                                     "nodes": nodes},
                         "uniform": {"intervals": n_uni, "error": _error(usol), "iterations": usol.solver["iterations"],
                                     "time_s": t_uni, "objective": usol.objective, "probes": probes,
                                     "nodes": unodes},
                         "fewer_intervals": fewer, "less_time": faster}
    return figures


if __name__ == "__main__":
    refinement_rows()
