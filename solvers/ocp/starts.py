"""Several starts (``search: {"starts": N}``, ``shared/specs/ocp.md``): the N initial guesses of one problem,
and what their answers say together.

An NLP solver finds a local optimum near where it starts; a problem with several (an obstacle passed on
either side, a well the straight-line guess does not reach) is searched by solving it from several
guesses.  Start 0 is the guess the problem gives (its straight lines, or a stored answer); start k >= 1
is :func:`start_guess`, by the rule :data:`RULE`, deterministic from ``(seed, k)``: the same starts on any
machine and in any worker.  :func:`distinct_optima` groups the answers' objectives within
:func:`group_tolerance`, so the result says how many local optima the starts met and how often.
"""
from __future__ import annotations

import math

import numpy as np

from solvers.ocp.flown import as_stored, clip, fly, phase_start, within_bounds
from solvers.ocp.grid import grid_of
from solvers.ocp.guess import stored_phases
from solvers.ocp.phase import positive_scale
from solvers.ocp.problem import OcpProblem
from solvers.ocp.scaling import control_scales, state_scales

TF_FACTOR = 2.0          # a free final time is re-scaled by a factor in [1/2, 2] (log-uniform)
STATE_BUMP = 0.25        # the states' bump, in their scales
GROUPING_FLOOR = 1e-5    # 10 x IPOPT's acceptable_tol (solvers.transcription.nlp): two answers of one optimum agree
                         # to it, relative

RULE = ("start 0 is the guess given (straight lines between the ends, or initial_guess.from_job); start k >= 1: "
        "each control held at one level, drawn uniformly from its own stratum of [lower, upper] (the N-1 "
        "strata of equal width, in a random order per control, so the starts spread over the bounds; a "
        "control without both bounds: its guess plus its scale times a standard normal), each parameter "
        "drawn the same way, a free final time re-scaled by a factor in [1/2, 2] (log-uniform, kept within "
        "its bounds), and the states flown from their initial values with those controls (LSODA, stopped "
        "before blowing up, clipped to their bounds, fixed ends kept), then re-scaled by a factor in [1/2, 2] "
        "about their initial values and bumped by s * scale * sin(pi * tau) with s uniform in [-0.25, 0.25] "
        "(tau the phase's normalized time); the random numbers are numpy's PCG64 seeded with (seed, k), "
        "strata permuted by PCG64 seeded with (seed, 0)")


def _level(rng: np.random.Generator, perm: np.ndarray, k: int, lo, hi, base: float, scale: float) -> float:
    """A value drawn for start k: uniform in its stratum of [lo, hi], else ``base`` plus a normal step."""
    if lo is not None and hi is not None and hi > lo:
        n = perm.size
        return float(lo + (hi - lo) * (perm[(k - 1) % n] + rng.uniform()) / n)
    return float(clip(base + scale * rng.standard_normal(), lo, hi))


def start_guess(problem: OcpProblem, *, index: int, starts: int, seed: int,
                initial_guess: dict | None = None) -> dict | None:
    """The guess of start ``index`` of ``starts`` (:data:`RULE`) in the form of a stored answer; start 0
    is ``initial_guess`` itself (None: the problem's own straight lines)."""
    if index == 0:
        return initial_guess
    strata = max(starts - 1, 1)
    order = np.random.default_rng([seed, 0])
    rng = np.random.default_rng([seed, index])
    stored = stored_phases(problem, initial_guess)
    perms: dict = {}

    def perm(key) -> np.ndarray:
        if key not in perms:
            perms[key] = order.permutation(strata)
        return perms[key]

    theta = None
    if problem.parameters:
        theta = np.array([_level(rng, perm(("parameter", q.name)), index, q.lower, q.upper,
                                 q.guess if q.guess is not None else 0.0, positive_scale(q.lower, q.upper, q.guess))
                          for q in problem.parameters])
    flights = []
    for ph in problem.phases:
        grid = grid_of(ph.problem)
        t0, tf, theta0, X, U = phase_start(ph, initial_guess, stored, grid)
        theta = theta0 if theta is None else theta
        time = ph.problem.phase.time
        if time.final is None:
            tf = t0 + (tf - t0) * math.exp(rng.uniform(-math.log(TF_FACTOR), math.log(TF_FACTOR)))
            lo, hi = time.final_lower, time.final_upper
            tf = min(max(tf, -np.inf if lo is None else lo), np.inf if hi is None else hi)
        U = U.copy()
        for i, (k, scale) in enumerate(zip(ph.problem.phase.controls, control_scales(ph.problem))):
            base = float(np.mean(U[i])) if U.shape[1] else 0.0
            U[i] = _level(rng, perm((ph.name, k.name)), index, k.lower, k.upper, base, float(scale))
        t, Xf, Uf, _ = fly(ph.problem, grid, t0=t0, tf=tf, theta=theta, X=X, U=U)
        tau = (t - t0) / max(tf - t0, 1e-300)
        for i, scale in enumerate(state_scales(ph.problem)):
            factor = math.exp(rng.uniform(-math.log(2.0), math.log(2.0)))
            Xf[i] = Xf[i, 0] + factor * (Xf[i] - Xf[i, 0]) + rng.uniform(-STATE_BUMP, STATE_BUMP) * float(scale) * np.sin(
                math.pi * tau)
        Xf = within_bounds(ph.problem.phase.states, Xf)
        flights.append({"t0": t0, "tf": tf, "t": t, "X": Xf, "U": Uf})
    guess = as_stored(problem, flights, theta if theta is not None else np.zeros(0))
    guess["start"] = index          # not a warm start: solvers.ocp.solver starts IPOPT cold from it
    return guess


def group_tolerance(problem: OcpProblem) -> float:
    """The relative difference under which two starts' objectives are one optimum: the answer's own accuracy
    when the problem asks one, else what IPOPT's acceptable tolerance leaves (:data:`GROUPING_FLOOR`)."""
    return max(problem.accuracy or 0.0, GROUPING_FLOOR)


def distinct_optima(objectives: list[float], *, tolerance: float, sense: str) -> list[dict]:
    """``[{"objective", "count"}]``, best first: the objectives grouped where they agree within ``tolerance``
    of their size (the floor of the size: ``tolerance`` times the largest objective, so optima near zero
    group by an absolute difference); a group's objective is its best member's."""
    values = sorted((float(v) for v in objectives if math.isfinite(v)), reverse=(sense == "maximize"))
    if not values:
        return []
    floor = max(abs(v) for v in values) * 1e-3
    groups: list[dict] = []
    for v in values:
        last = groups[-1] if groups else None
        if last is not None and abs(v - last["objective"]) <= tolerance * max(abs(v), abs(last["objective"]), floor):
            last["count"] += 1
        else:
            groups.append({"objective": v, "count": 1})
    return groups
